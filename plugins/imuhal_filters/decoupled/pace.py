"""How fast the decoupled filter's accelerometer low-pass may run: the gyro's error against
the accelerometer's, from what the filter sees.

The inclination is the strapdown corrected by a low-pass of the accelerometer in the
almost-inertial frame. Its time constant trades two errors:

- the **strapdown's**: a gyro's relative error (scale factor and cross-axis sensitivity, a
  few per cent on a MEMS gyro: the MPU-9250's datasheet gives +-3 % and +-2 %) turns the
  strapdown away at epsilon |omega| while the board rotates; the filter follows that
  drift with a lag of its time constant, so the error it leaves grows with tau;
- the **accelerometer's**: the kinematic acceleration the filter takes for gravity; it
  averages out over the time constant, so the error it leaves shrinks with tau.

Seen as a Kalman filter of the tilt (a random walk driven by the gyro's error, measured by
the accelerometer's direction with the kinematic acceleration as its noise), the steady gain
corresponds to a time constant of the measurement's noise over the process's: with both
disturbances coming from the same motion (the hand's strokes turn and push the board at the
same pace), tau = sigma_a / (g epsilon |omega|), sigma_a the RMS of the filter's innovation
across gravity (m/s^2) and |omega| the RMS rotation rate, both over the filter's own time
constant. ``tau_acc_s`` stays the longest it runs (VQF's 3 s: hand-held translation, where
the board barely turns, keeps it), and sigma_a counts at least ``floor_m_s2`` (the
manoeuvre detector's floor: below it the innovation is sensor noise and not an average's
worth). The filter then runs tau_acc_s / tau times as fast: a fast rotation with little
acceleration is corrected sooner (BROAD's rotation trials), hand-held translation and a
vehicle's manoeuvres (large accelerations for their rotation) keep the full time constant.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from imuhal.core.atmosphere import STANDARD_GRAVITY_M_S2
from imuhal_filters.common.quat import Vec


@dataclass(slots=True)
class RotationPace:
    """The RMS of the filter's innovation across gravity and of the rotation rate, each a
    first-order mean over ``tau_s``; ``factor`` is how many times faster than ``tau_s``
    the accelerometer filter runs."""

    tau_s: float
    gyro_relative_error: float
    floor_m_s2: float = 1.0
    innovation_sq_m2_s4: float = 0.0
    rate_sq_rad2_s2: float = 0.0
    started: bool = field(default=False)

    def as_list(self) -> list[float]:
        """The state, JSON-ready."""
        return [self.innovation_sq_m2_s4, self.rate_sq_rad2_s2, float(self.started)]

    def load_list(self, values: list[float]) -> None:
        self.innovation_sq_m2_s4, self.rate_sq_rad2_s2 = float(values[0]), float(values[1])
        self.started = bool(values[2])

    def step(self, reading_g: Vec, gravity_g: Vec | None, rate_rad_s: Vec, dt_s: float
             ) -> float:
        """Fold in one reading (g, almost-inertial frame) against the filter's gravity before
        it (None: not known yet) and the bias-corrected rotation rate (rad/s) over
        ``dt_s``; returns the factor (>= 1) the filter's step is to be lengthened by."""
        if gravity_g is None:
            return 1.0
        gx, gy, gz = gravity_g
        n_sq = gx * gx + gy * gy + gz * gz
        if n_sq < 1e-18:
            return 1.0
        g = STANDARD_GRAVITY_M_S2
        dx, dy, dz = g * (reading_g[0] - gx), g * (reading_g[1] - gy), g * (reading_g[2] - gz)
        along = (dx * gx + dy * gy + dz * gz) / math.sqrt(n_sq)
        across_sq = max(dx * dx + dy * dy + dz * dz - along * along, 0.0)
        w_sq = rate_rad_s[0] ** 2 + rate_rad_s[1] ** 2 + rate_rad_s[2] ** 2
        if not self.started:
            self.innovation_sq_m2_s4, self.rate_sq_rad2_s2, self.started = across_sq, w_sq, True
        else:
            k = 1.0 - math.exp(-dt_s / self.tau_s)
            self.innovation_sq_m2_s4 += k * (across_sq - self.innovation_sq_m2_s4)
            self.rate_sq_rad2_s2 += k * (w_sq - self.rate_sq_rad2_s2)
        return self.factor

    @property
    def factor(self) -> float:
        """tau_s over the time constant the errors call for, at least 1."""
        g_eps_w = (STANDARD_GRAVITY_M_S2 * self.gyro_relative_error
                   * math.sqrt(self.rate_sq_rad2_s2))
        sigma = max(math.sqrt(self.innovation_sq_m2_s4), self.floor_m_s2)
        if g_eps_w * self.tau_s <= sigma:
            return 1.0
        return g_eps_w * self.tau_s / sigma
