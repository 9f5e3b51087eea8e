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

``ManoeuvreDetector`` (below) is what decoupled uses by default instead: two statistics of
the same innovation that a hand cannot produce but a vehicle does.

This module is shared on purpose (any gravity filter can weight its steps by it).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from imuhal.core.atmosphere import STANDARD_GRAVITY_M_S2


def _direction(gravity_g: tuple[float, float, float] | None
               ) -> tuple[float, float, float] | None:
    """The unit vector along the filter's gravity (None: not known yet, or no length)."""
    if gravity_g is None:
        return None
    gx, gy, gz = gravity_g
    n = math.sqrt(gx * gx + gy * gy + gz * gz)
    if n < 1e-9:
        return None
    return (gx / n, gy / n, gz / n)


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
        u = _direction(gravity_g)
        if u is None or gravity_g is None:
            return 1.0
        gx, gy, gz = gravity_g
        ux, uy, uz = u
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


GAP_VELOCITY_KEPT = 0.5
"""The share of the manoeuvre detector's velocity kept across an accelerometer gap
(``ManoeuvreDetector.restart``; the compiled kernel reads it too)."""


@dataclass(frozen=True, slots=True)
class ManoeuvreParams:
    """The manoeuvre detector's constants (s, m/s, m/s^2; see ``ManoeuvreDetector``)."""

    speed_m_s: float = 8.0
    ratio: float = 1.0
    window_s: float = 0.5
    leak_s: float = 3.0
    drift_tau_s: float = 30.0
    floor_m_s2: float = 1.0
    power: float = 8.0


@dataclass(slots=True)
class ManoeuvreDetector:
    """Tells a vehicle's sustained acceleration from a hand's, from the gravity filter's
    innovation d (the reading minus the filter's gravity, almost-inertial frame, m/s^2).

    A board moved by hand stays within arm's reach: its velocity stays within a few m/s
    (BROAD's fast translations: the innovation integrated with a 3 s leak stays under 5.4
    m/s) and its acceleration reverses within a second, so over half a second the mean of
    d is small against its scatter (under 0.6 of it). A vehicle's manoeuvre does what no
    hand does, and each does one of the two:

    - **speed**: a loop, a pull-up, a turn or a take-off run changes the velocity by tens of
      m/s (``rc-flight``'s loop 21 m/s, its turn 25 m/s with the same leak): the leaky
      integral of d (``leak_s``), its whole vector (a loop's velocity change turns through
      the vertical), against ``speed_m_s``;
    - **steadiness**: a take-off push, a launch or a banked turn is a steady acceleration
      with little scatter: the mean of d over ``window_s`` across gravity (an acceleration
      along gravity does not tilt the estimate) against its scatter over the same window,
      with a floor ``floor_m_s2`` (sensor noise alone would make any mean look steady),
      against ``ratio``. A tilt error is a steady innovation too, and must always be
      corrected: for this statistic d's own mean over ``drift_tau_s`` (longer than any
      manoeuvre: no vehicle accelerates one way for half a minute) is taken out first.

    Each statistic s gives 1 / (1 + (s / bound)^power), a sharp step (power 8: 0.996 at
    half the bound, 0.004 at twice it), so hand motion keeps full weight and the weights of
    its phases stay even (a soft weight that depends on the acceleration spoils the
    averaging: docs/estimators.md); the product is the filter step's weight. Its users
    take it as a decision (a reading counts in full from one half up: the few per cent
    under 1 near the bounds still weighted the hand's phases unevenly, BROAD trial 18).
    Both statistics need a few tenths of a second to see a manoeuvre, which the filter has
    already partly absorbed by then: the decoupled kernel re-filters that stretch with the
    new weight, and filters it again in full if its velocity change comes back, as a
    hand's stroke does (decoupled/lookback.py). At rest ``reset`` zeroes the velocity and
    the window's mean (a zero-velocity update).
    """

    p: ManoeuvreParams
    drift_m_s2: list[float] = field(default_factory=lambda: [0.0, 0.0, 0.0])
    mean_m_s2: list[float] = field(default_factory=lambda: [0.0, 0.0, 0.0])
    mean_sq_m2_s4: float = 0.0
    v_m_s: list[float] = field(default_factory=lambda: [0.0, 0.0, 0.0])

    def reset(self) -> None:
        """Zero velocity and no steady acceleration (at rest)."""
        self.v_m_s = [0.0, 0.0, 0.0]
        self.mean_m_s2 = [0.0, 0.0, 0.0]

    def restart(self) -> None:
        """After the readings stopped for a while (an accelerometer gap): the window's mean
        and scatter (``window_s``) start again, as at start-up, since they are of readings
        long gone; the velocity (``leak_s``, 3 s, longer than a gap) is kept in part,
        ``GAP_VELOCITY_KEPT``; the drift (the filter's tilt error, ``drift_tau_s``) in
        full. Across the gap the velocity changed by what was not measured: a clip (the
        usual gap) is mid-manoeuvre, so zeroing it declares the board at rest, and keeping
        it whole judges the readings after the gap by a manoeuvre's phase that has passed.
        ``rc-flight``, tilt RMS/max in deg (Madgwick: seed board 2.07, GY-91 1.36): zeroed,
        seed 1.78/3.94 and GY-91 3.25/5.76; kept whole 2.05/5.43 and 2.11/4.83; half
        1.84/4.89 and 1.69/4.57 (0.4 to 0.6: seed 1.83-1.89, GY-91 1.60-1.74; 0.3: the
        GY-91 3.22 again). Restarting it as manoeuvring instead (raised to
        ``speed_m_s``) was worse on both (2.4-5.3 and 2.6-4.6): the gyro alone then carried
        the attitude past the manoeuvre (docs/reliability.md, session 21)."""
        self.mean_m_s2 = [0.0, 0.0, 0.0]
        self.mean_sq_m2_s4 = 0.0
        self.v_m_s = [GAP_VELOCITY_KEPT * c for c in self.v_m_s]

    def as_list(self) -> list[float]:
        """The state, JSON-ready."""
        return [*self.drift_m_s2, *self.mean_m_s2, self.mean_sq_m2_s4, *self.v_m_s]

    def load_list(self, values: list[float]) -> None:
        self.drift_m_s2 = [float(c) for c in values[0:3]]
        self.mean_m_s2 = [float(c) for c in values[3:6]]
        self.mean_sq_m2_s4 = float(values[6])
        self.v_m_s = [float(c) for c in values[7:10]]

    def weight(self, reading_g: tuple[float, float, float],
               gravity_g: tuple[float, float, float] | None, dt_s: float) -> float:
        """Fold in one reading (g, any sign convention, almost-inertial frame) against the
        filter's gravity before it (same frame and convention; None: not known yet, weight
        1) over ``dt_s``; returns the weight of this step, in (0, 1]."""
        u = _direction(gravity_g)
        if u is None or gravity_g is None:
            return 1.0
        p = self.p
        k_drift = 1.0 - math.exp(-dt_s / p.drift_tau_s)
        k_mean = 1.0 - math.exp(-dt_s / p.window_s)
        leak = math.exp(-dt_s / p.leak_s)
        drift, mean, v = self.drift_m_s2, self.mean_m_s2, self.v_m_s
        e_sq = 0.0
        for i, r in enumerate(reading_g):
            d = STANDARD_GRAVITY_M_S2 * (r - gravity_g[i])
            drift[i] += k_drift * (d - drift[i])
            e = d - drift[i]
            mean[i] += k_mean * (e - mean[i])
            v[i] = (v[i] + d * dt_s) * leak
            e_sq += e * e
        self.mean_sq_m2_s4 += k_mean * (e_sq - self.mean_sq_m2_s4)
        along = mean[0] * u[0] + mean[1] * u[1] + mean[2] * u[2]
        m_sq = mean[0] * mean[0] + mean[1] * mean[1] + mean[2] * mean[2]
        across = math.sqrt(max(m_sq - along * along, 0.0))
        scatter = math.sqrt(max(self.mean_sq_m2_s4 - m_sq, 0.0))
        steadiness = across / max(scatter, p.floor_m_s2)
        speed = math.sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2])
        return 1.0 / ((1.0 + (steadiness / p.ratio) ** p.power)
                      * (1.0 + (speed / p.speed_m_s) ** p.power))
