"""Straight flight through turbulence: when the decoupled filter may correct at a fixed rate.

The flight defaults' soft gate (0.02 g wide) lets the inclination filter advance only while
|a| is near 1 g. Turbulence keeps |a| away from 1 g all the time (``rc-flight``: the normal
load V q of the pitch gusts, about 0.33 g mean deviation in straight flight), so the gate
stays closed and the gyro error built up in aerobatics is never corrected
(docs/estimators.md, decoupled section). In straight flight the kinematic acceleration is
gusts about a constant velocity: zero mean, so the readings scatter around gravity and a
correction towards each reading at a fixed, capped rate (madgwick's kind) walks the attitude
back while the scatter averages out. The same correction would be wrong wherever the
acceleration has a mean: a sustained load (loop, pull-up, launch), which shows in |a| as a
mean offset, and a turn, which does not show in |a| at shallow bank (|a| = 1 / cos(bank)
g, second order) but does in the gyro's earth-vertical rate.

So straight flight through turbulence is declared after ``hold_s`` with, over a first-order
window of ``tau_s``:

- the spread of |a| - 1 g at least ``sd_min_g`` (the gate is closed by fluctuation; with a
  small spread a closed gate means a sustained offset, e.g. a launch's forward push);
- the mean of |a| - 1 g within ``mean_ratio`` of that spread (zero-mean fluctuation);
- the RMS of |a| - 1 g under ``rms_max_g`` (gusts, not aerobatics);
- the earth-vertical turn rate under ``turn_max_rad_s`` (not turning).

Values: docs/estimators.md (flight benchmark, `rc-flight` and `thermal`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from imuhal_filters.common.quat import Vec


@dataclass(frozen=True, slots=True)
class TurbulenceParams:
    """The detector's constants (s, g, rad/s; see the module docstring)."""

    tau_s: float = 1.0
    sd_min_g: float = 0.15
    mean_ratio: float = 0.3
    rms_max_g: float = 1.0
    turn_max_rad_s: float = math.radians(1.5)
    hold_s: float = 0.5


class StraightFlightDetector:
    """Tracks the statistics of |a| - 1 g and the turn rate; ``steady`` once they have held
    for ``hold_s``."""

    def __init__(self, params: TurbulenceParams) -> None:
        self.p = params
        self.dev_mean_g = 0.0
        self.dev_sq_g2 = 0.0
        self.turn_rate_rad_s = 0.0
        self.held_s = 0.0

    @property
    def steady(self) -> bool:
        return self.held_s >= self.p.hold_s

    def step(self, acc_g: Vec, vertical_rate_rad_s: float, dt: float) -> bool:
        """One accelerometer reading (g, any sign convention) and the gyro's earth-vertical
        rate (rad/s) over ``dt`` s; returns ``steady``."""
        p = self.p
        k = 1.0 - math.exp(-dt / p.tau_s)
        dev = math.sqrt(acc_g[0] * acc_g[0] + acc_g[1] * acc_g[1] + acc_g[2] * acc_g[2]) - 1.0
        self.dev_mean_g += k * (dev - self.dev_mean_g)
        self.dev_sq_g2 += k * (dev * dev - self.dev_sq_g2)
        self.turn_rate_rad_s += k * (vertical_rate_rad_s - self.turn_rate_rad_s)
        var = max(self.dev_sq_g2 - self.dev_mean_g * self.dev_mean_g, 0.0)
        ok = (var >= p.sd_min_g * p.sd_min_g
              and abs(self.dev_mean_g) <= p.mean_ratio * math.sqrt(var)
              and self.dev_sq_g2 < p.rms_max_g * p.rms_max_g
              and abs(self.turn_rate_rad_s) < p.turn_max_rad_s)
        self.held_s = self.held_s + dt if ok else 0.0
        return self.steady

    def as_list(self) -> list[float]:
        return [self.dev_mean_g, self.dev_sq_g2, self.turn_rate_rad_s, self.held_s]

    def load_list(self, values: list[float]) -> None:
        self.dev_mean_g, self.dev_sq_g2, self.turn_rate_rad_s, self.held_s = (
            float(v) for v in values)
