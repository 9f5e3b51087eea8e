"""What every calibration procedure shares: it is fed samples and says when it is done.

Procedures are push-style state machines over raw sensor-frame samples, so the same object
runs on hardware (fed from ``Pipeline.open(..., calibrated=False).events()``), on an emulated
board and on a recorded log. They never do I/O: they report through a progress callback and
return a result (or raise :class:`~imuhal.calibration.errors.CalibrationError`).
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Iterable
from typing import Generic, TypeVar

from imuhal.calibration.progress import Progress, ProgressCallback, ProgressKind, ignore
from imuhal.core.samples import Frame, Sample, VectorSample

R = TypeVar("R")


class Procedure(ABC, Generic[R]):
    """Feed samples with :meth:`feed` until it returns True, then call :meth:`finish`.

    ``device``: only samples of this device are used (None: every sample fed). Flagged
    samples (overflow, NaN, stale) are counted and skipped.
    """

    name: str = "procedure"

    def __init__(self, *, device: str | None = None,
                 progress: ProgressCallback | None = None) -> None:
        self.device = device
        self._progress = progress or ignore
        self.skipped = 0
        self.done = False

    def feed(self, sample: Sample) -> bool:
        """Take one sample; True once the procedure has all it needs."""
        if self.done:
            return True
        if self.device is not None and sample.device != self.device:
            return False
        if isinstance(sample, VectorSample) and sample.frame is not Frame.SENSOR:
            raise ValueError(
                f"{self.name}: got a {sample.frame.value}-frame sample from {sample.device!r}; "
                "calibration measures raw sensor-frame samples (open the pipeline with "
                "calibrated=False)")
        if not sample.valid:
            self.skipped += 1
            return False
        self.done = self._take(sample)
        return self.done

    def run(self, samples: Iterable[Sample]) -> R:
        """Feed ``samples`` until done (or exhausted), then :meth:`finish`."""
        for sample in samples:
            if self.feed(sample):
                break
        return self.finish()

    @abstractmethod
    def _take(self, sample: Sample) -> bool:
        """Use one valid sample of the device; True when done."""

    @abstractmethod
    def finish(self) -> R:
        """The result; raises CalibrationError saying what is missing if it cannot be had."""

    def say(self, kind: ProgressKind, message: str, fraction: float | None = None,
            step: str = "") -> None:
        self._progress(Progress(self.name, kind, message, fraction, step))
