"""mpu9250: see plugin.py."""
