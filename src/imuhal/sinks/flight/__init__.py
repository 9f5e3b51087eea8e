"""Flight-app output: NMEA-style sentences (LK8EX1, LX LXWP0, OpenVario POV, FlyNet _PRS,
XC Tracer XCTRC, GGA/RMC) over a serial port, a pseudo-terminal or TCP, and vario audio.
Formats and sources: docs/flight-instrument.md."""

from imuhal.sinks.flight.audio import AudioSink, ToneGenerator, VarioAudioSettings
from imuhal.sinks.flight.sink import FlightOutputSettings, FlightSink, check_sentences
from imuhal.sinks.flight.transports import (
    PtyTransport,
    SerialTransport,
    TcpTransport,
    TransportSpec,
    check_transport,
    open_transport,
)

__all__ = ["AudioSink", "FlightOutputSettings", "FlightSink", "PtyTransport",
           "SerialTransport", "TcpTransport", "ToneGenerator", "TransportSpec",
           "VarioAudioSettings", "check_sentences", "check_transport", "open_transport"]
