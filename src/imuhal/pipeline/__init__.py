"""The pipeline: poll devices on one clock, decode, calibrate, rotate, estimate, sink."""

from imuhal.pipeline.pipeline import Pipeline, RunSummary
from imuhal.pipeline.sinks import CallbackSink, ConsoleSink, CsvSink, Sink, TruthSink

__all__ = [
    "CallbackSink", "ConsoleSink", "CsvSink", "Pipeline", "RunSummary", "Sink", "TruthSink",
]
