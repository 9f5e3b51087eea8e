"""Low-pass and down-sample IMU-rate vertical acceleration to the barometer rate.

The seed runs the AHRS at the IMU rate (200-250 Hz) and the Kalman filter at the barometer
rate (30-40 Hz), feeding it one acceleration per altitude sample. Averaging every acceleration
since the previous barometer sample is that low-pass (a boxcar matched to the baro interval)
and that down-sampling in one step; it is also exactly the mean acceleration over the interval
the prediction integrates across.
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass
class IntervalMean:
    """Running mean of upward acceleration (m/s^2) since the last ``take``."""

    total: float = 0.0
    count: int = 0

    def add(self, accel_up_m_s2: float) -> None:
        self.total += accel_up_m_s2
        self.count += 1

    def take(self) -> float | None:
        """The mean since the last take (None if nothing arrived), and start a new interval."""
        mean = self.total / self.count if self.count else None
        self.total, self.count = 0.0, 0
        return mean

    def as_dict(self) -> dict[str, float | int]:
        return {"total": self.total, "count": self.count}

    def load_dict(self, d: dict[str, float | int]) -> None:
        self.total, self.count = float(d["total"]), int(d["count"])
