"""Accelerometer six-position calibration (the seed's "Accelerometer" procedure).

The board is held still with each sensor axis pointing down, then up. A still accelerometer
measures specific force: with axis ``i`` pointing down it reads ``-g`` on that axis (imuhal's
convention: level at rest reads (0, 0, -g) in NED), with it pointing up ``+g``. With ``up``
and ``down`` the averaged readings of axis ``i`` in those two positions, the seed's formulas
(there in counts and gravity-positive, here in m/s^2) give::

    sensitivity_i = (up_i - down_i) / (2 g)      # gain, 1.0 for a perfect axis
    offset_i      = (up_i + down_i) / 2          # = up_i - g * sensitivity_i, m/s^2
    scale_i       = 1 / sensitivity_i

Optionally the full model ``true = M diag(s) (raw - b)`` is fitted by linear least squares
over all recorded positions (six or more), assuming the case faces are square to each other:
``true = A raw + c`` with ``A = M diag(s)``, ``b = -A^-1 c``; M gets a unit diagonal.
Quality: the gravity magnitude error ``| |corrected| - g |`` at each position, in mg.
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from datetime import datetime

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, field_validator

from imuhal.calibration.errors import CalibrationError
from imuhal.calibration.model import AccelCalibration
from imuhal.calibration.procedure import Procedure
from imuhal.calibration.progress import ProgressCallback, ProgressKind
from imuhal.calibration.stillness import DEG, Spread, StillnessLimits
from imuhal.core.atmosphere import STANDARD_GRAVITY_M_S2
from imuhal.core.frames import FloatArray, Vector
from imuhal.core.samples import AccelSample, GyroSample, Sample

MG = STANDARD_GRAVITY_M_S2 * 1e-3
PROCEDURE = "accel-six-position"
PROCEDURE_LSQ = "accel-six-position-lsq"

Position = tuple[int, int]
"""(sensor axis 0..2, +1 when that axis points down / -1 when it points up)."""
SIX_POSITIONS: tuple[Position, ...] = ((2, -1), (2, 1), (0, 1), (0, -1), (1, 1), (1, -1))
"""The seed's order: level (sensor z up), upside down, x down, x up, y down, y up."""


def position_name(p: Position) -> str:
    return f"{'+' if p[1] > 0 else '-'}{'xyz'[p[0]]} down"


def parse_position(name: str) -> Position:
    text = name.strip().lower().replace("_", " ")
    if len(text) >= 2 and text[0] in "+-" and text[1] in "xyz" and text[2:].strip() == "down":
        return ("xyz".index(text[1]), 1 if text[0] == "+" else -1)
    raise ValueError(f"{name!r} is not a position; write e.g. '+z down' or '-x down'")


def expected_specific_force(p: Position, g: float = STANDARD_GRAVITY_M_S2) -> FloatArray:
    """What a perfect accelerometer reads (m/s^2, sensor frame) still in position ``p``."""
    v = np.zeros(3)
    v[p[0]] = -p[1] * g
    return v


# --------------------------------------------------------------------------- the maths
def six_position_fit(means: Mapping[Position, Vector],
                     g: float = STANDARD_GRAVITY_M_S2) -> tuple[FloatArray, FloatArray]:
    """(offset m/s^2, scale) per axis from the six averaged readings, by the seed's formulas."""
    offset, scale = np.zeros(3), np.ones(3)
    for axis in range(3):
        up, down = means[(axis, -1)][axis], means[(axis, 1)][axis]
        sensitivity = (up - down) / (2.0 * g)
        if sensitivity <= 0.1:
            raise CalibrationError(
                f"accelerometer {'xyz'[axis]} axis: reads {down:+.2f} m/s^2 pointing down and "
                f"{up:+.2f} pointing up (sensitivity {sensitivity:.3f})",
                "check the axis is not dead or the positions swapped, then repeat")
        offset[axis] = (up + down) / 2.0
        scale[axis] = 1.0 / sensitivity
    return offset, scale


def least_squares_fit(raw: Sequence[Vector], truth: Sequence[Vector]
                      ) -> tuple[FloatArray, FloatArray, FloatArray]:
    """(offset b, scale s, misalignment M) with ``truth ~ M diag(s) (raw - b)``; M has a unit
    diagonal. Needs at least four positions not in one plane (the six give 18 equations for
    12 unknowns)."""
    r = np.asarray(raw, dtype=float)
    t = np.asarray(truth, dtype=float)
    x = np.c_[r, np.ones(len(r))]
    if len(r) < 4 or np.linalg.matrix_rank(x) < 4:
        raise CalibrationError("too few distinct accelerometer positions for the 3x3 fit",
                               "record all six positions (each axis down, then up)")
    p, *_ = np.linalg.lstsq(x, t, rcond=None)
    a = p[:3].T
    b = -np.linalg.solve(a, p[3])
    s = np.diag(a).copy()
    return b, s, a / s[None, :]


def gravity_errors_mg(cal: AccelCalibration, raw: Sequence[Vector],
                      g: float = STANDARD_GRAVITY_M_S2) -> FloatArray:
    """``|corrected| - g`` (mg) for still readings ``raw``."""
    return np.array([(np.linalg.norm(cal.apply(_t3(v))) - g) / MG for v in raw])


# --------------------------------------------------------------------------- the procedure
class AccelSixSettings(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)

    positions: tuple[str, ...] = tuple(position_name(p) for p in SIX_POSITIONS)
    """Positions to record, in the order the user is asked for them (any order is accepted)."""
    samples: int = Field(250, ge=10)
    """Readings averaged per position (1 s at 250 Hz)."""
    still_window: int = Field(50, ge=5)
    """Readings over which stillness is judged before recording starts."""
    max_accel_std_m_s2: float = Field(0.05, gt=0)
    max_gyro_std_dps: float = Field(1.0, gt=0)
    max_drift_m_s2: float = Field(0.01, gt=0)
    """The two halves of the averaged readings must agree this well (settling, creeping)."""
    max_tilt_deg: float = Field(15.0, gt=0, lt=45)
    """How far the requested axis may be from vertical."""
    gravity_m_s2: float = Field(STANDARD_GRAVITY_M_S2, gt=9.7, lt=9.9)
    """Local gravity (the calibration makes |corrected| equal to it)."""
    misalignment: bool = False
    """Also fit the full 3x3 misalignment by least squares."""

    @field_validator("positions")
    @classmethod
    def _positions(cls, v: tuple[str, ...]) -> tuple[str, ...]:
        parsed = [parse_position(n) for n in v]
        missing = [position_name(p) for p in SIX_POSITIONS if p not in parsed]
        if missing:
            raise ValueError(f"all six positions are needed; missing: {', '.join(missing)}")
        if len(set(parsed)) != len(parsed):
            raise ValueError("a position is listed twice")
        return tuple(position_name(p) for p in parsed)


@dataclass(frozen=True)
class AccelSixResult:
    offset_m_s2: FloatArray
    scale: FloatArray
    misalignment: FloatArray
    means: dict[Position, FloatArray]
    """Averaged raw reading per position (m/s^2, sensor frame)."""
    gravity_error_mg: FloatArray
    """``|corrected| - g`` per recorded position after calibration (mg)."""
    gravity_error_before_mg: FloatArray
    procedure: str

    @property
    def quality(self) -> dict[str, float]:
        e, e0 = self.gravity_error_mg, self.gravity_error_before_mg
        return {
            "positions": float(len(self.means)),
            "gravity_error_rms_mg": float(np.sqrt(np.mean(e**2))),
            "gravity_error_max_mg": float(np.max(np.abs(e))),
            "uncalibrated_gravity_error_rms_mg": float(np.sqrt(np.mean(e0**2))),
        }

    def record(self, date: datetime | None = None) -> AccelCalibration:
        return AccelCalibration(
            offset_m_s2=_t3(self.offset_m_s2), scale=_t3(self.scale),
            misalignment=(_t3(self.misalignment[0]), _t3(self.misalignment[1]),
                          _t3(self.misalignment[2])),
            procedure=self.procedure, date=date, quality=self.quality)


def accel_result(means: Mapping[Position, Vector], *,
                 g: float = STANDARD_GRAVITY_M_S2, misalignment: bool = False) -> AccelSixResult:
    """Fit averaged still readings (the six positions, at least) as the procedure does."""
    m = {p: np.asarray(v, dtype=float) for p, v in means.items()}
    raw = [m[p] for p in m]
    if misalignment:
        truth = [expected_specific_force(p, g) for p in m]
        b, s, mis = least_squares_fit(raw, truth)
        name = PROCEDURE_LSQ
    else:
        b, s = six_position_fit(m, g)
        mis, name = np.eye(3), PROCEDURE
    cal = AccelCalibration(offset_m_s2=_t3(b), scale=_t3(s),
                           misalignment=(_t3(mis[0]), _t3(mis[1]), _t3(mis[2])))
    return AccelSixResult(b, s, mis, m, gravity_errors_mg(cal, raw, g),
                          gravity_errors_mg(AccelCalibration(), raw, g), name)


class AccelSixPosition(Procedure[AccelSixResult]):
    """Feed raw samples of one device (accel, and gyro when it has one).

    ``describe`` turns a sensor position into words for the user (the CLI says which side of
    the board goes down, through the mount); the default names the sensor axis.
    """

    name = PROCEDURE

    def __init__(self, settings: AccelSixSettings | None = None, *, device: str | None = None,
                 progress: ProgressCallback | None = None,
                 describe: Callable[[Position], str] | None = None) -> None:
        super().__init__(device=device, progress=progress)
        self.settings = s = settings or AccelSixSettings()
        self.order = [parse_position(n) for n in s.positions]
        self.describe = describe or (lambda p: f"sensor {position_name(p)}")
        self.limits = StillnessLimits(s.max_accel_std_m_s2, s.max_gyro_std_dps * DEG)
        self.means: dict[Position, FloatArray] = {}
        self._window: deque[tuple[float, float, float]] = deque(maxlen=s.still_window)
        self._gyro: deque[tuple[float, float, float]] = deque(maxlen=s.still_window)
        self._buffer: deque[tuple[float, float, float]] = deque(maxlen=s.samples)
        self._current: Position | None = None
        self._started = False

    @property
    def missing(self) -> list[Position]:
        return [p for p in self.order if p not in self.means]

    def _ask_next(self) -> None:
        nxt = self.missing
        if nxt:
            done = len(self.means)
            self.say(ProgressKind.INSTRUCTION,
                     f"position {done + 1}/{len(self.order)}: {self.describe(nxt[0])}, and hold "
                     "it still", done / len(self.order), position_name(nxt[0]))

    def _take(self, sample: Sample) -> bool:
        if not self._started:
            self._started = True
            self._ask_next()
        if isinstance(sample, GyroSample):
            self._gyro.append(sample.gyro_rad_s)
            return False
        if not isinstance(sample, AccelSample):
            return False
        v = sample.accel_m_s2
        self._window.append(v)
        if len(self._window) < self._window.maxlen:  # type: ignore[operator]  # the window is created with a maxlen
            return False
        accel = Spread.of(self._window)
        gyro = Spread.of(self._gyro) if len(self._gyro) > 1 else None
        if self.limits.problems(accel, gyro):
            if len(self._buffer) > self.settings.samples // 4 and self._current is not None:
                self.say(ProgressKind.RETRY, f"moved while recording {self.describe(self._current)}"
                         "; hold it still", step=position_name(self._current))
            self._reset()
            return False
        pos = self._classify(accel.mean)
        if pos is None or pos in self.means:
            self._reset()
            return False
        if pos != self._current:
            self._reset()
            self._current = pos
            self.say(ProgressKind.PROGRESS, f"recording {self.describe(pos)}", 0.0,
                     position_name(pos))
        self._buffer.append(v)
        n = len(self._buffer)
        if n % 50 == 0 and n < self.settings.samples:
            self.say(ProgressKind.PROGRESS, f"recording {self.describe(pos)}",
                     n / self.settings.samples, position_name(pos))
        if n == self.settings.samples and self._settled():
            self.means[pos] = np.mean(np.asarray(self._buffer), axis=0)
            self.say(ProgressKind.STEP_DONE, f"recorded {self.describe(pos)}", 1.0,
                     position_name(pos))
            self._reset()
            if not self.missing:
                return True
            self._ask_next()
        return False

    def _reset(self) -> None:
        self._buffer.clear()
        self._current = None

    def _settled(self) -> bool:
        a = np.asarray(self._buffer)
        half = len(a) // 2
        drift = np.max(np.abs(a[:half].mean(axis=0) - a[half:].mean(axis=0)))
        return bool(drift <= self.settings.max_drift_m_s2)

    def _classify(self, mean: FloatArray) -> Position | None:
        """The position a still reading shows, or None between positions."""
        norm = float(np.linalg.norm(mean))
        g = self.settings.gravity_m_s2
        if not 0.75 * g < norm < 1.25 * g:
            return None
        axis = int(np.argmax(np.abs(mean)))
        if abs(mean[axis]) / norm < math.cos(math.radians(self.settings.max_tilt_deg)):
            return None
        return (axis, -1 if mean[axis] > 0 else 1)

    def finish(self) -> AccelSixResult:
        missing = self.missing
        if missing:
            names = ", ".join(self.describe(p) for p in missing)
            secs = self.settings.samples + self.settings.still_window
            raise CalibrationError(
                f"only {len(self.means)} of {len(self.order)} accelerometer positions recorded; "
                f"missing: {names}",
                f"place the board in each missing position and hold it still (about {secs} "
                "samples each) until it is recorded",
                {"positions": float(len(self.means))})
        return accel_result(self.means, g=self.settings.gravity_m_s2,
                            misalignment=self.settings.misalignment)


def _t3(v: Vector) -> tuple[float, float, float]:
    return (float(v[0]), float(v[1]), float(v[2]))
