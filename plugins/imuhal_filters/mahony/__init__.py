"""mahony: see plugin.py."""
