"""freescale: see plugin.py."""
