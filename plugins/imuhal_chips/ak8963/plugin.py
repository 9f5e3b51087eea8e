"""Entry point of the ak8963 plugin. Its hook implementations are being written."""
