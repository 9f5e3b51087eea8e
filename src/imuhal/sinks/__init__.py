"""Where pipeline events go (sinks know samples and estimates, nothing about buses)."""

from imuhal.sinks.base import Event, Sink, SinkPlugin
from imuhal.sinks.builtin import CSV_COLUMNS, CallbackSink, ConsoleSink, CsvSink, event_row

__all__ = ["CSV_COLUMNS", "CallbackSink", "ConsoleSink", "CsvSink", "Event", "Sink",
           "SinkPlugin", "event_row"]
