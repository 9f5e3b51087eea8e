"""Flight-app output: NMEA-style sentences (LK8EX1, OpenVario POV, FlyNet _PRS, XC Tracer
XCTRC, GGA/RMC) over a serial port, a pseudo-terminal or TCP, and vario audio.
Formats and sources: docs/flight-instrument.md."""
