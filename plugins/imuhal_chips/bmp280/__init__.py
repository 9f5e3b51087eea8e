"""bmp280: see plugin.py."""
