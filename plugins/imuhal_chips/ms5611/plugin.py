"""Entry point of the ms5611 plugin. Its hook implementations are being written."""
