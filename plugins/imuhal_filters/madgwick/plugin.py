"""Entry point of the madgwick plugin. Its hook implementations are being written."""
