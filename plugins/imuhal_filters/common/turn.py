"""Turn compensation: the kinematic acceleration an AHRS removes before it corrects the tilt.

An accelerometer measures specific force f = a - g. An AHRS corrects its tilt towards -f as
if a were zero; in a coordinated turn a is the centripetal acceleration, f points at the
"apparent" vertical and the filter rolls towards the bank angle (docs/estimators.md: 15-17 deg
tilt RMS in ``thermal`` without compensation). Every AHRS therefore subtracts this module's
estimate of a (body axes, m/s^2) from f before the tilt correction; the gravity-compensated
acceleration they publish still comes from the raw f.

Sources, best first (the first one available at a gyro step is used):

1. **Velocity over ground** (``VelocitySample``, NED, e.g. a GNSS receiver). The speed
   through the air is what turns with the vehicle; the wind only drifts it. While circling,
   the horizontal ground velocities of the last ``wind_window_s`` lie on a circle whose
   centre is the wind and whose radius is the airspeed (a least-squares circle fit, used
   once the samples taken while turning cover at least a third of the circle); until then
   the nominal airspeed, if one is configured, stands for V, else the ground speed (later
   fits are used as they come). The airspeed V and its rate of change V' (least-squares
   slope over ``velocity_rate_window_s``; not used while turning before the wind is known,
   when the ground speed swings with the heading) give a = omega x (V, 0, 0) + V' (1, 0, 0):
   the centripetal term from the gyro and the speed, the longitudinal term from the rate of
   change of the velocity source. Below 2 m/s (standing) nothing is compensated. This needs
   no heading, so 6-DOF filters (arbitrary yaw) use it too.
2. **Airspeed** (``AirspeedSample``, along body x): the same formula, V' from the low-passed
   rate of change of the airspeed samples.
3. **Nominal airspeed** (``nominal_airspeed_m_s`` setting, along body x): a = omega x (V, 0,
   0). Cheap and good for a paraglider or a glider at trim speed (``thermal`` flies 10 m/s).

With none of them there is nothing to compensate and f is fused unchanged.
"""

from __future__ import annotations

import itertools
import math
from collections import deque
from collections.abc import Iterable
from typing import Any

from pydantic import Field

from imuhal.core.frames import FloatArray
from imuhal.core.samples import AirspeedSample, VelocitySample
from imuhal.estimation.base import EstimatorSettings
from imuhal_filters.common.quat import Vec

_NS = 1e-9
_ZERO: Vec = (0.0, 0.0, 0.0)


class TurnCompensationSettings(EstimatorSettings):
    """Where the kinematic acceleration comes from (see ``imuhal_filters.common.turn``)."""

    turn_compensation: bool = True
    """Subtract the kinematic acceleration from the specific force before the tilt
    correction. It does nothing without a speed source (velocity, airspeed or nominal)."""
    nominal_airspeed_m_s: float | None = Field(default=None, ge=0.0)
    """Speed along body x (m/s) when no velocity or airspeed sample is fresh; None: none."""
    speed_max_age_s: float = Field(default=1.0, gt=0.0)
    """A velocity or airspeed sample older than this no longer counts as a source."""
    wind_window_s: float = Field(default=25.0, gt=0.0)
    """Ground velocities of this long (s) are fitted with a circle to find wind and airspeed
    while circling (a thermal circle takes about 20 s)."""
    airspeed_rate_tau_s: float = Field(default=0.3, gt=0.0)
    """Low-pass time constant of an airspeed sensor's rate of change (s)."""
    velocity_rate_window_s: float = Field(default=1.0, gt=0.0)
    """The rate of change of the speed from velocity samples is the least-squares slope over
    this window (s): a GNSS receiver's 0.1 m/s noise differentiated sample to sample at 5 Hz
    would be 0.7 m/s^2; the slope over 1 s has about 0.14 m/s^2 and lags half a window."""


class KinematicAcceleration:
    """The acceleration estimate of one AHRS; call ``step`` once per gyro sample."""

    def __init__(self, settings: TurnCompensationSettings) -> None:
        self.s = settings
        self.reset()

    def reset(self) -> None:
        self.wind_ne_m_s: tuple[float, float] = (0.0, 0.0)
        self._ground: deque[tuple[int, float, float]] = deque()
        self._turn_sum = 0.0
        self._turn_n = 0
        self._turning = False
        self._speed = _SlopeSpeed()
        self._airspeed = _Speed()
        self.source = "none"
        self.counts = {"velocity_samples": 0, "airspeed_samples": 0, "wind_fits": 0,
                       "compensated_steps": 0}

    # -- inputs -----------------------------------------------------------------------------

    def on_velocity(self, sample: VelocitySample) -> None:
        """A ground velocity: refit the wind when circling, update the airspeed."""
        self.counts["velocity_samples"] += 1
        vn, ve, _ = sample.velocity_ned_m_s
        turning = self._turn_n > 0 and self._turn_sum / self._turn_n >= _MIN_TURN_RAD_S
        self._turning = turning
        self._turn_sum, self._turn_n = 0.0, 0
        if turning:  # straight-line points all sit at one angle: they only bias the circle
            self._ground.append((sample.t_ns, vn, ve))
        while self._ground and (sample.t_ns - self._ground[0][0]) * _NS > self.s.wind_window_s:
            self._ground.popleft()
        fit = _circle_fit(self._ground)
        if fit is not None:
            self.wind_ne_m_s = fit
            self.counts["wind_fits"] += 1
        self._speed.add_ground(sample.t_ns, vn, ve, self.wind_ne_m_s,
                               self.s.velocity_rate_window_s)

    def on_airspeed(self, sample: AirspeedSample) -> None:
        self.counts["airspeed_samples"] += 1
        self._airspeed.add(sample.t_ns, sample.airspeed_m_s, self.s.airspeed_rate_tau_s)

    # -- per gyro step ----------------------------------------------------------------------

    def step(self, t_ns: int | None, gyro_rad_s: Vec) -> Vec:
        """Kinematic acceleration (body axes, m/s^2) at this gyro step."""
        if not self.s.turn_compensation:
            self.source = "off"
            return _ZERO
        self.count_turn(gyro_rad_s)
        source, acceleration = self.acceleration(t_ns, gyro_rad_s)
        if source != "none":
            self.source = source
            self.counts["compensated_steps"] += 1
        return acceleration

    def acceleration(self, t_ns: int | None, gyro_rad_s: Vec) -> tuple[str, Vec]:
        """The speed source ``step`` would compensate with at ``t_ns`` (``velocity``,
        ``airspeed``, ``nominal`` or ``none``) and its kinematic acceleration for the gyro
        rate (body axes, m/s^2), changing nothing (no count, no turn bookkeeping): what a
        check of the compensated specific force asks (the AHRS's recovery). It does not
        depend on the attitude: the body moves along its own x axis."""
        nominal = self.s.nominal_airspeed_m_s
        # (a source that never sent a sample is not fresh: skip the calls, once per step)
        if self._speed.t_ns is not None and self._speed.fresh(t_ns, self.s.speed_max_age_s):
            # until a circle has shown the wind, a configured trim speed is the better guess
            # of the airspeed, and while turning the ground speed swings with the heading
            # (wind), so its rate of change is not the airspeed's
            wind_known = self.counts["wind_fits"] > 0
            if self._speed.value < _MIN_AIRSPEED_M_S:
                return "velocity", _ZERO  # standing: the velocity is noise, and its rate
            speed = self._speed.value if wind_known or nominal is None else nominal
            rate = self._speed.rate if wind_known or not self._turning else 0.0
            return "velocity", _along_x(gyro_rad_s, speed, rate)
        if self._airspeed.t_ns is not None and self._airspeed.fresh(t_ns,
                                                                    self.s.speed_max_age_s):
            return "airspeed", _along_x(gyro_rad_s, self._airspeed.value, self._airspeed.rate)
        if nominal is not None:
            return "nominal", _along_x(gyro_rad_s, nominal, 0.0)
        return "none", _ZERO

    def count_turn(self, gyro_rad_s: Vec) -> None:
        """The turn detector's bookkeeping of one gyro step with compensation on, and
        ``source`` "none" (what ``step`` leaves without a speed source; the caller knows
        there is none)."""
        self._turn_sum += math.sqrt(gyro_rad_s[0] ** 2 + gyro_rad_s[1] ** 2 + gyro_rad_s[2] ** 2)
        self._turn_n += 1
        self.source = "none"

    # -- batch kernels ----------------------------------------------------------------------

    @property
    def has_speed_source(self) -> bool:
        """A velocity or airspeed sample has arrived (``update()`` would compensate with it)."""
        return self._speed.t_ns is not None or self._airspeed.t_ns is not None

    @property
    def turn_sum(self) -> float:
        """Running sum of |gyro| over the steps (the turn detector's input)."""
        return self._turn_sum

    def add_turn_steps(self, turn_sum: float, steps: int) -> None:
        """What ``steps`` calls of ``step`` without a velocity or airspeed source would have
        left: a compiled batch kernel accumulated ``turn_sum`` from :attr:`turn_sum` in the
        same order, and fused the specific force less :func:`nominal_rows` when a nominal
        airspeed is set."""
        if not self.s.turn_compensation:
            self.source = "off"
            return
        self._turn_sum = turn_sum
        self._turn_n += steps
        if steps:
            if self.s.nominal_airspeed_m_s is None:
                self.source = "none"
            else:
                self.source = "nominal"
                self.counts["compensated_steps"] += steps

    # -- state ------------------------------------------------------------------------------

    def as_dict(self) -> dict[str, Any]:
        return {"wind_ne_m_s": list(self.wind_ne_m_s),
                "ground": [list(g) for g in self._ground],
                "speed": self._speed.as_dict(), "airspeed": self._airspeed.as_dict(),
                "turn": [self._turn_sum, self._turn_n, self._turning],
                "counts": dict(self.counts)}

    def load_dict(self, d: dict[str, Any]) -> None:
        wn, we = d["wind_ne_m_s"]
        self.wind_ne_m_s = (float(wn), float(we))
        self._ground = deque((int(t), float(n), float(e)) for t, n, e in d["ground"])
        self._speed.load_dict(d["speed"])
        self._airspeed.load_dict(d["airspeed"])
        turn_sum, turn_n, turning = d["turn"]
        self._turn_sum, self._turn_n, self._turning = float(turn_sum), int(turn_n), bool(turning)
        self.counts = {k: int(v) for k, v in d["counts"].items()}


class _Speed:
    """A speed (m/s) from a sampled source and its low-passed rate of change (m/s^2)."""

    def __init__(self) -> None:
        self.value = 0.0
        self.rate = 0.0
        self.t_ns: int | None = None

    def add(self, t_ns: int, value: float, tau_s: float) -> None:
        if self.t_ns is not None:
            dt = (t_ns - self.t_ns) * _NS
            if dt <= 0.0:
                return
            k = min(1.0, dt / tau_s)
            self.rate += k * ((value - self.value) / dt - self.rate)
        self.value, self.t_ns = value, t_ns

    def fresh(self, now_ns: int | None, max_age_s: float) -> bool:
        if self.t_ns is None:
            return False
        return now_ns is None or (now_ns - self.t_ns) * _NS <= max_age_s

    def as_dict(self) -> dict[str, Any]:
        return {"value": self.value, "rate": self.rate, "t_ns": self.t_ns}

    def load_dict(self, d: dict[str, Any]) -> None:
        self.value, self.rate, self.t_ns = float(d["value"]), float(d["rate"]), d["t_ns"]


class _SlopeSpeed(_Speed):
    """Airspeed from ground velocities and a wind, and the least-squares slope of the
    airspeed over a window (m/s^2). The whole window is re-evaluated with the newest wind, so
    a better wind estimate is not mistaken for an acceleration."""

    def __init__(self) -> None:
        super().__init__()
        self._window: deque[tuple[int, float, float]] = deque()

    def add_ground(self, t_ns: int, vn: float, ve: float, wind_ne: tuple[float, float],
                   window_s: float) -> None:
        if self.t_ns is not None and t_ns <= self.t_ns:
            return
        self._window.append((t_ns, vn, ve))
        while (t_ns - self._window[0][0]) * _NS > window_s:
            self._window.popleft()
        wn, we = wind_ne
        speeds = [math.hypot(n - wn, e - we) for _, n, e in self._window]
        self.value, self.t_ns = speeds[-1], t_ns
        count = len(speeds)
        ts = [(t - t_ns) * _NS for t, _, _ in self._window]
        mt = sum(ts) / count
        mv = sum(speeds) / count
        den = sum((t - mt) ** 2 for t in ts)
        self.rate = 0.0 if count < 2 or den == 0.0 else sum(
            (t - mt) * (v - mv) for t, v in zip(ts, speeds, strict=True)) / den

    def as_dict(self) -> dict[str, Any]:
        return {**super().as_dict(), "window": [list(w) for w in self._window]}

    def load_dict(self, d: dict[str, Any]) -> None:
        super().load_dict(d)
        self._window = deque((int(t), float(n), float(e)) for t, n, e in d.get("window", []))


_MIN_AIRSPEED_M_S = 2.0
_MIN_TURN_RAD_S = 0.1
"""Ground velocities enter the wind fit only while the vehicle turns at least this fast."""
_MIN_ARC_RAD = 2.0 * math.pi / 3.0
"""A circle fit counts only when the samples span at least a third of a turn around it."""


def _circle_fit(points: Iterable[tuple[int, float, float]]) -> tuple[float, float] | None:
    """Centre (north, east; m/s) of the circle through the ground velocities, or None when
    they do not describe one (too few, too little of the circle, too small a radius)."""
    pts = [(n, e) for _, n, e in points]
    if len(pts) < 10:
        return None
    # algebraic (Kasa) fit: n^2 + e^2 + D n + E e + F = 0, linear least squares
    sxx = sxy = syy = sx = sy = 0.0
    sxz = syz = sz = 0.0
    for n, e in pts:
        z = n * n + e * e
        sxx += n * n
        sxy += n * e
        syy += e * e
        sx += n
        sy += e
        sxz += n * z
        syz += e * z
        sz += z
    m = len(pts)
    a = ((sxx, sxy, sx), (sxy, syy, sy), (sx, sy, float(m)))
    b = (-sxz, -syz, -sz)
    sol = _solve3(a, b)
    if sol is None:
        return None
    d, e_, f = sol
    cn, ce = -d / 2.0, -e_ / 2.0
    r2 = cn * cn + ce * ce - f
    if r2 < _MIN_AIRSPEED_M_S**2:
        return None
    angles = sorted(math.atan2(e - ce, n - cn) for n, e in pts)
    gaps = [b2 - a2 for a2, b2 in itertools.pairwise(angles)]
    gaps.append(angles[0] + 2.0 * math.pi - angles[-1])
    if 2.0 * math.pi - max(gaps) < _MIN_ARC_RAD:
        return None
    return cn, ce


def _solve3(a: tuple[tuple[float, float, float], ...], b: tuple[float, float, float]
            ) -> tuple[float, float, float] | None:
    """Cramer's rule for a 3x3 system; None when it is (nearly) singular."""
    def det(m: tuple[tuple[float, float, float], ...]) -> float:
        return (m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1])
                - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0])
                + m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0]))

    d = det(a)
    scale = max(abs(c) for row in a for c in row)
    if scale == 0.0 or abs(d) < 1e-12 * scale**3:
        return None
    out = []
    for col in range(3):
        m = tuple(tuple(b[r] if c == col else a[r][c] for c in range(3)) for r in range(3))
        out.append(det(m) / d)  # type: ignore[arg-type]  # three rows of three, built by the comprehension from 3x3 inputs
    return out[0], out[1], out[2]


def _along_x(gyro_rad_s: Vec, speed_m_s: float, speed_rate_m_s2: float) -> Vec:
    """omega x (V, 0, 0) + (V', 0, 0): a body moving along its own x axis."""
    _, q, r = gyro_rad_s
    return (speed_rate_m_s2, r * speed_m_s, -q * speed_m_s)


def nominal_rows(specific_force_m_s2: FloatArray, gyro_rad_s: FloatArray, speed_m_s: float
                 ) -> FloatArray:
    """:func:`compensated` by the nominal airspeed's kinematic acceleration
    (:func:`_along_x` with no rate of change), row by row on (m, 3) arrays: the same products
    and differences, so the same floats as ``KinematicAcceleration.step`` and the AHRS's
    ``_run_step`` one step at a time; a row whose kinematic acceleration is zero (no turn)
    is left as it is there too. NaN rows (no accelerometer) stay NaN."""
    f, g = specific_force_m_s2, gyro_rad_s
    ky = g[:, 2] * speed_m_s
    kz = -g[:, 1] * speed_m_s
    on = (ky != 0.0) | (kz != 0.0)
    out = f.copy()  # x less the step's 0.0 is x itself (-0.0 included)
    out[on, 1] = f[on, 1] - ky[on]
    out[on, 2] = f[on, 2] - kz[on]
    return out


def compensated(specific_force_m_s2: Vec, kinematic_m_s2: Vec) -> Vec:
    """The specific force with the kinematic acceleration removed: what gravity alone gives."""
    f, a = specific_force_m_s2, kinematic_m_s2
    return (f[0] - a[0], f[1] - a[1], f[2] - a[2])
