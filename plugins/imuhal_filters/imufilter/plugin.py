"""Entry point of the imufilter plugin. Its hook implementations are being written."""
