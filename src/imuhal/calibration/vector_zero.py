"""Zero offsets of any vector quantity, measured at rest (``imuhal calibrate vector-zero
PROFILE --quantity Q``).

For a quantity that reads zero when nothing happens (air flow in still air, a differential
field, a plugin's vector): average ``samples`` readings and store their mean as the offset
(``VectorCalibration``: corrected = raw - offset). If the readings spread more than
``max_std`` (in the quantity's unit) the window is discarded and measured again, at most
``max_attempts`` times.
"""

from __future__ import annotations

import math
from typing import ClassVar

import numpy as np
from pydantic import BaseModel, ConfigDict, Field

from imuhal.calibration.errors import CalibrationError
from imuhal.calibration.model import VectorCalibration
from imuhal.calibration.procedure import CalibrationProcedure
from imuhal.calibration.progress import ProgressKind
from imuhal.core.samples import Sample, VectorSample


class VectorZeroSettings(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)

    samples: int = Field(100, ge=10, le=100_000)
    """Readings averaged per attempt."""
    max_std: float = Field(math.inf, gt=0)
    """Largest per-axis spread (quantity's unit) of a window kept as "at rest"."""
    max_attempts: int = Field(5, ge=1)


class VectorZeroProcedure(CalibrationProcedure):
    """Offsets of a vector quantity at rest (any vector quantity; ``--quantity``)."""

    name = "vector-zero"
    description: ClassVar[str] = "zero offsets of any vector quantity, measured at rest"
    Settings = VectorZeroSettings

    def __init__(self, settings: BaseModel, **kwargs: object) -> None:
        super().__init__(settings, **kwargs)  # type: ignore[arg-type]  # the registered procedure validates its own Settings model
        self._window: list[tuple[float, float, float]] = []
        self.attempts = 1
        self._result: VectorCalibration | None = None
        self.say(ProgressKind.INSTRUCTION,
                 f"keep the board still: measuring the {self.calibrated_quantity} offsets")

    def _take(self, sample: Sample) -> bool:
        if not isinstance(sample, VectorSample) or \
                sample.channel.name != self.calibrated_quantity:
            return False
        s: VectorZeroSettings = self.settings  # type: ignore[assignment]  # the plugin's own Settings model: the base class types settings as the base model
        self._window.append(sample.vector)
        self.say(ProgressKind.PROGRESS, "averaging", len(self._window) / s.samples)
        if len(self._window) < s.samples:
            return False
        window = np.asarray(self._window)
        std = window.std(axis=0)
        if float(std.max()) > s.max_std:
            if self.attempts >= s.max_attempts:
                raise CalibrationError(
                    f"{self.calibrated_quantity} spread {float(std.max()):.4g} above max_std "
                    f"{s.max_std:g} in all {s.max_attempts} attempts",
                    "keep the board still (or raise max_std)")
            self.attempts += 1
            self._window = []
            self.say(ProgressKind.RETRY, "the readings moved; measuring again")
            return False
        mean = window.mean(axis=0)
        self._result = VectorCalibration(
            offset=(float(mean[0]), float(mean[1]), float(mean[2])), procedure=self.name,
            quality={"samples": float(len(window)), "attempts": float(self.attempts),
                     "std_max": float(std.max()),
                     "offset_std_error": float(std.max()) / math.sqrt(len(window))})
        return True

    def finish(self) -> VectorCalibration:
        if self._result is None:
            raise CalibrationError(
                f"only {len(self._window)} {self.calibrated_quantity} readings arrived",
                "run longer (--timeout) or check that the device produces them")
        return self._result
