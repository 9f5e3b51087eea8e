"""Gyro offsets at rest (the seed's "Gyroscope" procedure).

Average ``samples`` gyro readings (default 100: 0.4 s at 250 Hz) with the board still. If any
axis reads more than ``max_offset_dps`` ("larger than expected"), or the board moved during the
window (gyro or accelerometer spread above the stillness limits), wait ``retry_wait_s`` and
repeat, at most ``max_attempts`` times. Only offsets are measured; scale and misalignment
already stored are kept (the offset is in raw units, so it does not depend on them).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from datetime import datetime

import numpy as np
from pydantic import Field

from imuhal.calibration.errors import CalibrationError
from imuhal.calibration.model import GyroCalibration, GyroStartupSettings
from imuhal.calibration.procedure import Procedure
from imuhal.calibration.progress import ProgressCallback, ProgressKind
from imuhal.calibration.stillness import DEG, Spread, StillnessLimits
from imuhal.core.frames import FloatArray
from imuhal.core.samples import AccelSample, GyroSample, Sample, SampleFlag

PROCEDURE = "gyro-at-rest"


class GyroOffsetSettings(GyroStartupSettings):
    """The start-up measurement's knobs for the one-off procedure (``imuhal calibrate
    gyro``), which waits for a board being set down: five attempts by default, where the
    start-up measurement gives up after one (a board moving at switch-on may be flying)."""

    max_attempts: int = Field(5, ge=1)


@dataclass(frozen=True)
class GyroOffsetResult:
    offset_rad_s: FloatArray
    """Mean gyro reading at rest, sensor frame (rad/s)."""
    gyro_std_rad_s: FloatArray
    """Per-axis spread of the window (rad/s): the noise the offset was averaged over."""
    accel_std_m_s2: FloatArray | None
    samples: int
    attempts: int

    @property
    def quality(self) -> dict[str, float]:
        q = {
            "samples": float(self.samples),
            "attempts": float(self.attempts),
            "gyro_std_dps": float(np.max(self.gyro_std_rad_s) / DEG),
            "offset_std_error_dps": float(np.max(self.gyro_std_rad_s) / DEG
                                          / math.sqrt(self.samples)),
        }
        if self.accel_std_m_s2 is not None:
            q["accel_std_mg"] = float(np.max(self.accel_std_m_s2) / 9.80665e-3)
        return q

    def record(self, existing: GyroCalibration | None = None,
               date: datetime | None = None) -> GyroCalibration:
        """A stored record with these offsets (scale/misalignment kept from ``existing``)."""
        base = existing or GyroCalibration()
        off = tuple(float(x) for x in self.offset_rad_s)
        return base.model_copy(update={"offset_rad_s": off, "procedure": PROCEDURE,
                                       "date": date, "quality": self.quality, "binding": None})


NOT_A_MEASUREMENT = SampleFlag.STALE | SampleFlag.BLANK | SampleFlag.FROZEN
"""Flags of a sample that is no measurement at all (the driver says so)."""
NO_MEASUREMENT_GIVE_UP_NS = 30_000_000_000
"""A chip that has sent nothing but samples flagged as no measurement (FROZEN, STALE, BLANK)
for 30 s ends the procedure: a hung gyro would otherwise hold it, and a start-up phase with
the whole run's output, for ever. Far longer than the attempts of a working chip take."""


class GyroOffsetProcedure(Procedure[GyroOffsetResult]):
    """Feed raw samples of one device (gyro, and accel when it has one)."""

    name = PROCEDURE

    def __init__(self, settings: GyroStartupSettings | None = None, *,
                 device: str | None = None,
                 progress: ProgressCallback | None = None) -> None:
        super().__init__(device=device, progress=progress)
        self.settings = settings or GyroOffsetSettings()
        s = self.settings
        self.limits = StillnessLimits(max_accel_std_m_s2=s.max_accel_std_m_s2,
                                      max_gyro_std_rad_s=s.max_gyro_std_dps * DEG)
        self.attempts = 0
        self.failures: list[str] = []
        self._gyro: list[tuple[float, float, float]] = []
        self._accel: list[tuple[float, float, float]] = []
        self._resume_ns: int | None = None
        self._result: GyroOffsetResult | None = None
        self._started = False
        self._only_large = False
        self.moved = False
        """The last attempt failed because the board moved (the gyro or accelerometer
        spread beyond the stillness limits, every sample a measurement): not a hung chip's
        repeats nor an offset beyond ``max_offset_dps``."""
        self._not_measured: dict[str, int] = {}
        """Flagged samples (no measurement) in the current window, by flag."""
        self._only_flagged_since_ns: int | None = None
        """Since when the device has sent only flagged samples (None: a valid one came)."""

    def _take(self, sample: Sample) -> bool:
        self._only_flagged_since_ns = None  # a measurement came
        if not self._started:
            self._started = True
            self.say(ProgressKind.INSTRUCTION,
                     f"keep the board still: measuring gyro offsets over {self.settings.samples} "
                     "samples")
        if self._resume_ns is not None:
            if sample.t_ns < self._resume_ns:
                return False
            self._resume_ns = None
        if isinstance(sample, AccelSample):
            self._accel.append(sample.accel_m_s2)
        elif isinstance(sample, GyroSample):
            self._gyro.append(sample.gyro_rad_s)
            n = len(self._gyro)
            if n % 10 == 0 or n == self.settings.samples:
                self.say(ProgressKind.PROGRESS, f"{n}/{self.settings.samples} samples",
                         n / self.settings.samples)
            if n >= self.settings.samples:
                return self._evaluate(sample.t_ns)
        return False

    def _flagged(self, sample: Sample) -> None:
        """A sample the driver says is no measurement (FROZEN, STALE, BLANK) is counted for
        the window's verdict: a frozen run is flagged only from its Nth repeat, so the
        repeats before it came in valid and, joined to live samples, looked like a board
        that moved. A failed window then says its data were not all measurements."""
        flags = sample.flags & NOT_A_MEASUREMENT
        if not flags or (self._resume_ns is not None and sample.t_ns < self._resume_ns):
            return
        for flag in SampleFlag:
            if flag and flag in flags:
                name = str(flag.name)  # a member of the enumeration: always named
                self._not_measured[name] = self._not_measured.get(name, 0) + 1
        if self._only_flagged_since_ns is None:
            self._only_flagged_since_ns = sample.t_ns
        elif sample.t_ns - self._only_flagged_since_ns >= NO_MEASUREMENT_GIVE_UP_NS:
            self.failures.append(
                f"for {NO_MEASUREMENT_GIVE_UP_NS / 1e9:g} s only "
                f"{self._not_measured_text()}")
            self._fail()

    def _not_measured_text(self) -> str:
        counts = ", ".join(f"{n} {name}" for name, n in sorted(self._not_measured.items()))
        self._not_measured = {}
        return f"samples flagged as no measurement ({counts}): the chip may be hung"

    def _evaluate(self, t_ns: int) -> bool:
        s = self.settings
        self.attempts += 1
        gyro = Spread.of(self._gyro)
        accel = Spread.of(self._accel) if len(self._accel) > 1 else None
        problems = self.limits.problems(accel, gyro)
        self.moved = bool(problems) and not self._not_measured
        large = [f"gyro {'xyz'[i]} reads {gyro.mean[i] / DEG:+.2f} deg/s (more than the "
                 f"expected {s.max_offset_dps:g} deg/s)"
                 for i in range(3) if abs(gyro.mean[i]) > s.max_offset_dps * DEG]
        self._only_large = bool(large) and not problems
        problems += large
        if self._not_measured:
            text = self._not_measured_text()
            if problems:  # the spread may be a hung chip's repeats joined to live samples
                problems.insert(0, text)
        self._gyro, self._accel = [], []
        if not problems:
            self._result = GyroOffsetResult(gyro.mean, gyro.std,
                                            None if accel is None else accel.std,
                                            gyro.count, self.attempts)
            self.say(ProgressKind.STEP_DONE, "gyro offsets measured")
            return True
        self._retry(t_ns, problems)
        return False

    def _retry(self, t_ns: int, problems: list[str]) -> None:
        """A failed attempt (counted): give up after ``max_attempts``, else wait and measure
        again."""
        s = self.settings
        self.failures.append("; ".join(problems))
        if self.attempts >= s.max_attempts:
            self._fail()
        self.say(ProgressKind.RETRY, f"attempt {self.attempts}: {'; '.join(problems)}; keep the "
                 f"board still, retrying in {s.retry_wait_s:g} s")
        self._resume_ns = t_ns + round(s.retry_wait_s * 1e9)

    def _fail(self) -> None:
        s = self.settings
        last = self.failures[-1] if self.failures else "no gyro samples arrived"
        if self._only_large:
            advice = ("if the board really was still, this chip's offset is larger than "
                      f"{s.max_offset_dps:g} deg/s: raise max_offset_dps")
        elif self._only_flagged_since_ns is not None:
            advice = "the chip sends no measurements: check its power and wiring, restart it"
        else:
            advice = "put the board on a steady table, do not touch it, and run again"
        raise CalibrationError(
            f"gyro offsets not measured after {self.attempts} attempt(s): {last}", advice,
            {"attempts": float(self.attempts)})

    def finish(self) -> GyroOffsetResult:
        if self._result is None:
            if not self.failures:
                raise CalibrationError(
                    f"gyro offsets not measured: only {len(self._gyro)} of "
                    f"{self.settings.samples} gyro samples arrived",
                    "check that the device streams gyro data and give the procedure more time")
            self._fail()
        assert self._result is not None
        return self._result
