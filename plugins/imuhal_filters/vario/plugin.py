"""Entry point of the vario plugin. Its hook implementations are being written."""
