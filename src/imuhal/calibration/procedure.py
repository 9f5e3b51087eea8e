"""What every calibration procedure shares: it is fed samples and says when it is done.

Procedures are push-style state machines over raw sensor-frame samples, so the same object
runs on hardware (fed from ``Pipeline.open(..., calibrated=False).events()``), on an emulated
board and on a recorded log. They never do I/O: they report through a progress callback and
return a result (or raise :class:`~imuhal.calibration.errors.CalibrationError`).
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Iterable
from typing import ClassVar, Generic, TypeVar

from pydantic import BaseModel

from imuhal.calibration.model import Record
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
            self._flagged(sample)
            return False
        self.done = self._take(sample)
        return self.done

    def _flagged(self, sample: Sample) -> None:
        """A flagged sample of the device arrived (it is skipped); a procedure whose window
        it taints restarts the window here."""

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


class CalibrationProcedure(Procedure[Record]):
    """A procedure a plugin registers (``imuhal_register_calibrations``) so that
    ``imuhal calibrate NAME PROFILE`` runs it and stores what :meth:`finish` returns.

    ``quantity`` names the quantity it calibrates, or None for a procedure that works on any
    vector quantity (``imuhal calibrate NAME --quantity Q``). ``Settings`` (a pydantic model)
    takes ``--set KEY=VALUE``. :meth:`finish` returns the record to store under the
    quantity's name (for a plugin's quantity: a
    :class:`~imuhal.calibration.model.VectorCalibration`); the runner adds the binding to
    the probed chip and the date.
    """

    quantity: ClassVar[str | None] = None
    description: ClassVar[str] = ""
    Settings: ClassVar[type[BaseModel]]
    default_timeout_s: ClassVar[float] = 60.0
    """How long ``imuhal calibrate`` waits on real hardware before giving up."""

    def __init__(self, settings: BaseModel, *, quantity: str, device: str | None = None,
                 progress: ProgressCallback | None = None) -> None:
        super().__init__(device=device, progress=progress)
        self.settings = settings
        self.calibrated_quantity = quantity
