"""The runtime pipeline: polls a board's devices, processes samples, feeds estimators/sinks."""

from imuhal.pipeline.board import Board, HardwareBoard
from imuhal.pipeline.pipeline import Pipeline, RunSummary
from imuhal.sinks import CallbackSink, ConsoleSink, CsvSink, Event, Sink

__all__ = ["Board", "CallbackSink", "ConsoleSink", "CsvSink", "Event", "HardwareBoard",
           "Pipeline", "RunSummary", "Sink"]
