"""Entry point of the bmp280 plugin. Its hook implementations are being written."""
