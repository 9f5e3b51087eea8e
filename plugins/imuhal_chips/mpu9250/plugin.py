"""Entry point of the mpu9250 plugin. Its hook implementations are being written."""
