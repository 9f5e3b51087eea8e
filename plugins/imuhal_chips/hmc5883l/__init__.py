"""hmc5883l: see plugin.py."""
