"""MS5611-01BA03 barometer plugin: commands, compensation, driver and emulator."""
