"""Entry point of the freescale plugin. Its hook implementations are being written."""
