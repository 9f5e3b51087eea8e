"""HMC5883L (Honeywell) magnetometer driver and register-level emulator; see plugin.py."""
