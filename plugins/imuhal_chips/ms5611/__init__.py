"""ms5611: see plugin.py."""
