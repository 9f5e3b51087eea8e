"""vario: see plugin.py."""
