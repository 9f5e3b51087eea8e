"""madgwick: see plugin.py."""
