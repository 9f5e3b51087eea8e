"""GNSS receivers on a UART (NMEA 0183 and u-blox UBX): driver and byte-stream emulator."""
