"""imufilter: see plugin.py."""
