"""ak8963: see plugin.py."""
