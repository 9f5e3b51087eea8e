"""Entry point of the hmc5883l plugin. Its hook implementations are being written."""
