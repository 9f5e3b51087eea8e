"""max2110x: see plugin.py."""
