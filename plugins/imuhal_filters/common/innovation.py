"""The accelerometer innovation integrated into a speed: how far a gravity filter may trust
the readings of the motion it sees.

An AHRS takes the (turn-compensated) specific force as gravity. What it gets wrong is the
kinematic acceleration a, and what matters is not the size of a at an instant but whether
it **averages out** over the filter's time constant:

- a board moved by hand, gusts in straight flight, vibration: the board stays where it was
  (or flies on at its speed), so a integrates to a velocity that stays small and comes back,
  and a low-pass of the specific force in an almost-inertial frame averages it away (VQF's
  point; a gate on |a| - 1 g weights such motion unevenly and starves the filter: BROAD,
  docs/evaluation.md);
- a coordinated turn without a speed source, a launch's forward push, a loop: a sustained
  acceleration, which integrates to a velocity change of metres per second within a second
  and biases any average of the specific force by that change over the time constant.

So the innovation of the inclination filter (the reading minus the filter's gravity, both
in the almost-inertial frame, in m/s^2) is integrated into a speed, with a leak of
``tau_s`` (the time over which hand motion and gusts come back: a velocity kept for longer
is a manoeuvre's), and only its part across gravity counts (an acceleration along gravity
does not tilt the estimate). The filter advances by the weight 1 / (1 + (v / speed)^2) of
each step: hand-held and gust speeds (well under ``speed_m_s``) keep most of it, a turn or a
push gates it within a fraction of a second. At rest the velocity is zero by definition
(``reset``: the rest detector's zero-velocity update).

A tilt error also shows as an innovation (g sin(error) across gravity), constant in the
almost-inertial frame, where no vehicle accelerates one way for long; so the innovation's own
mean over ``mean_tau_s`` (the filter's time constant) is taken out before the integration:
a tilt error stops counting as motion within a few of those, and the filter always
converges. The price: an acceleration that turns round slower than that (a slow turn without
a speed source) is taken for a tilt error too.

Measured (docs/estimators.md, decoupled ``preset: adaptive``, and vqf's
``withhold_speed_m_s``): right for flight, but BROAD's fast hand-held translation exceeds
any bound low enough to gate a turn, so neither estimator uses it by default.

This module is shared on purpose (any gravity filter can weight its steps by it).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from imuhal.core.atmosphere import STANDARD_GRAVITY_M_S2


@dataclass(slots=True)
class InnovationSpeed:
    """The leaky integral (m/s) of the inclination filter's innovation across gravity."""

    tau_s: float
    speed_m_s: float
    mean_tau_s: float
    v_m_s: list[float] = field(default_factory=lambda: [0.0, 0.0, 0.0])
    mean_g: list[float] = field(default_factory=lambda: [0.0, 0.0, 0.0])

    def reset(self) -> None:
        """Zero velocity (at rest)."""
        self.v_m_s = [0.0, 0.0, 0.0]

    def as_list(self) -> list[float]:
        """The state (velocity m/s, then the innovation's mean g), JSON-ready."""
        return [*self.v_m_s, *self.mean_g]

    def load_list(self, values: list[float]) -> None:
        self.v_m_s = [float(c) for c in values[:3]]
        self.mean_g = [float(c) for c in values[3:6]]

    def weight(self, reading_g: tuple[float, float, float],
               gravity_g: tuple[float, float, float] | None, dt_s: float) -> float:
        """Fold in one reading (g, any sign convention, almost-inertial frame) against the
        filter's gravity before it (same frame and convention; None: not known yet, weight
        1) over ``dt_s``; returns the weight of this step, in (0, 1]."""
        if gravity_g is None:
            return 1.0
        gx, gy, gz = gravity_g
        n = math.sqrt(gx * gx + gy * gy + gz * gz)
        if n < 1e-9:
            return 1.0
        ux, uy, uz = gx / n, gy / n, gz / n
        k = STANDARD_GRAVITY_M_S2 * dt_s
        leak = math.exp(-dt_s / self.tau_s)
        v, m = self.v_m_s, self.mean_g
        km = 1.0 - math.exp(-dt_s / self.mean_tau_s)
        for i, d in enumerate((reading_g[0] - gx, reading_g[1] - gy, reading_g[2] - gz)):
            m[i] += km * (d - m[i])
            v[i] = (v[i] + k * (d - m[i])) * leak
        along = v[0] * ux + v[1] * uy + v[2] * uz
        across_sq = max(v[0] * v[0] + v[1] * v[1] + v[2] * v[2] - along * along, 0.0)
        return 1.0 / (1.0 + across_sq / (self.speed_m_s * self.speed_m_s))
