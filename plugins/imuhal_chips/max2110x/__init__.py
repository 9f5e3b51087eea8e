"""MAX21100 / MAX21105 (Maxim) IMU drivers and register-level emulators; see plugin.py."""
