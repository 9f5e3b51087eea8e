"""Entry point of the mahony plugin. Its hook implementations are being written."""
