"""Entry point of the max2110x plugin. Its hook implementations are being written."""
