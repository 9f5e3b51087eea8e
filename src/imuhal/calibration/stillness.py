"""Is the board still? Spread of accelerometer and gyroscope samples over a window.

A board at rest shows only sensor noise: per-axis standard deviations of a few mg and a few
hundredths of a deg/s on the chips imuhal drives. Handling, vibration or a slow turn raise
them well above that, so thresholds between the two separate "still" from "moving" (the seed:
"some sort of indication to the user so that the unit can be undisturbed").
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from imuhal.core.frames import FloatArray

DEG = math.pi / 180.0


@dataclass(frozen=True, slots=True)
class Spread:
    """Per-axis mean and standard deviation of a window of 3-axis samples (SI units)."""

    mean: FloatArray
    std: FloatArray
    count: int

    @classmethod
    def of(cls, rows: Sequence[Sequence[float]] | FloatArray) -> Spread:
        a = np.asarray(rows, dtype=float).reshape(-1, 3)
        if len(a) == 0:
            return cls(np.full(3, np.nan), np.full(3, np.nan), 0)
        return cls(a.mean(axis=0), a.std(axis=0, ddof=1) if len(a) > 1 else np.zeros(3),
                   len(a))

    @property
    def max_std(self) -> float:
        return float(np.max(self.std)) if self.count else math.nan


@dataclass(frozen=True, slots=True)
class StillnessLimits:
    """Largest per-axis standard deviations of a still board."""

    max_accel_std_m_s2: float = 0.1
    max_gyro_std_rad_s: float = 0.5 * DEG

    def problems(self, accel: Spread | None, gyro: Spread | None) -> list[str]:
        """Why a window is not still (empty when it is). A missing channel is not checked."""
        out = []
        if accel is not None and accel.count > 1 and accel.max_std > self.max_accel_std_m_s2:
            out.append(f"the board moved (accelerometer spread {accel.max_std * 1e3 / 9.80665:.1f}"
                       f" mg > {self.max_accel_std_m_s2 * 1e3 / 9.80665:.1f} mg)")
        if gyro is not None and gyro.count > 1 and gyro.max_std > self.max_gyro_std_rad_s:
            out.append(f"the board moved (gyro spread {gyro.max_std / DEG:.2f} deg/s > "
                       f"{self.max_gyro_std_rad_s / DEG:.2f} deg/s)")
        return out
