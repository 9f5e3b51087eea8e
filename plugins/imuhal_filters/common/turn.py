"""Turn compensation: the kinematic acceleration an AHRS removes before it corrects the tilt.

An accelerometer measures specific force f = a - g. An AHRS corrects its tilt towards -f as
if a were zero; in a coordinated turn a is the centripetal acceleration, f points at the
"apparent" vertical and the filter rolls towards the bank angle (docs/estimators.md: 15-17 deg
tilt RMS in ``thermal`` without compensation). Every AHRS therefore subtracts this module's
estimate of a (body axes, m/s^2) from f before the tilt correction; the gravity-compensated
acceleration they publish still comes from the raw f.

Sources, best first (the first one available at a gyro step is used):

1. **Velocity over ground** (``VelocitySample``, NED, e.g. a GNSS receiver; its ``t_ns`` is
   the measurement epoch, so its latency is accounted for). The velocity through the air u
   turns with the vehicle; the wind w does not. A small observer propagates u with the
   earth-frame angular rate from the gyro at the gyro rate (u' = Omega x u + s' u/|u|) and
   corrects u, the wind and the longitudinal acceleration s' from each velocity sample
   compared with the propagated u + w at the sample's epoch. The kinematic acceleration is
   Omega x u + s' u/|u|: the centripetal term from the gyro and the speed, the longitudinal
   term from the rate of change of the velocity source.
2. **Airspeed** (``AirspeedSample``, along body x): a = omega x (V, 0, 0) + V' (1, 0, 0), V'
   from the low-passed rate of change of the airspeed samples.
3. **Nominal airspeed** (``nominal_airspeed_m_s`` setting, along body x): a = omega x (V, 0,
   0). Cheap and good for a paraglider or a glider at trim speed (``thermal`` flies 10 m/s).

With none of them there is nothing to compensate and f is fused unchanged.
"""

from __future__ import annotations

from collections import deque
from typing import Any

from pydantic import Field

from imuhal.core.samples import AirspeedSample, VelocitySample
from imuhal.estimation.base import EstimatorSettings
from imuhal_filters.common.quat import Quat, Vec, cross, norm3, to_global, to_local

_NS = 1e-9
_ZERO: Vec = (0.0, 0.0, 0.0)
_HISTORY_S = 1.0
"""How far back the propagated airspeed vector is kept to meet a late velocity sample."""


class TurnCompensationSettings(EstimatorSettings):
    """Where the kinematic acceleration comes from (see ``imuhal_filters.common.turn``)."""

    turn_compensation: bool = True
    """Subtract the kinematic acceleration from the specific force before the tilt
    correction. It does nothing without a speed source (velocity, airspeed or nominal)."""
    nominal_airspeed_m_s: float | None = Field(default=None, ge=0.0)
    """Speed along body x (m/s) when no velocity or airspeed sample is fresh; None: none."""
    speed_max_age_s: float = Field(default=1.0, gt=0.0)
    """A velocity or airspeed sample older than this no longer counts as a source."""
    velocity_gain: float = Field(default=0.3, gt=0.0, le=1.0)
    """Share of each velocity sample's innovation given to the airspeed vector."""
    wind_gain: float = Field(default=0.02, ge=0.0, le=1.0)
    """Share given to the wind estimate (horizontal); small: the wind changes slowly."""
    speed_rate_gain: float = Field(default=0.1, ge=0.0, le=1.0)
    """Share given to the longitudinal acceleration (per velocity sample interval)."""
    airspeed_rate_tau_s: float = Field(default=0.5, gt=0.0)
    """Low-pass time constant of the airspeed's rate of change (s)."""


class KinematicAcceleration:
    """The acceleration estimate of one AHRS; call ``step`` once per gyro sample."""

    def __init__(self, settings: TurnCompensationSettings) -> None:
        self.s = settings
        self.reset()

    def reset(self) -> None:
        self.u: Vec | None = None
        """Velocity through the air, NED (m/s); None until a velocity sample arrived."""
        self.wind: Vec = _ZERO
        self.speed_rate = 0.0
        self.velocity_t_ns: int | None = None
        self.airspeed: float | None = None
        self.airspeed_t_ns: int | None = None
        self.airspeed_rate = 0.0
        self._history: deque[tuple[int, Vec]] = deque()
        self.source = "none"
        self.counts = {"velocity_samples": 0, "airspeed_samples": 0, "compensated_steps": 0}

    # -- inputs -----------------------------------------------------------------------------

    def on_velocity(self, sample: VelocitySample) -> None:
        v = sample.velocity_ned_m_s
        self.counts["velocity_samples"] += 1
        if self.u is None:
            self.u, self.wind, self.speed_rate = v, _ZERO, 0.0
            self.velocity_t_ns = sample.t_ns
            self._history.clear()
            return
        u_then = self._u_at(sample.t_ns)
        e = (v[0] - u_then[0] - self.wind[0], v[1] - u_then[1] - self.wind[1],
             v[2] - u_then[2] - self.wind[2])
        ku, kw = self.s.velocity_gain, self.s.wind_gain
        u = self.u
        self.u = (u[0] + ku * e[0], u[1] + ku * e[1], u[2] + ku * e[2])
        self.wind = (self.wind[0] + kw * e[0], self.wind[1] + kw * e[1], self.wind[2])
        speed = norm3(self.u)
        if self.velocity_t_ns is not None and speed > 1.0:
            interval = (sample.t_ns - self.velocity_t_ns) * _NS
            if interval > 0.0:
                along = (e[0] * self.u[0] + e[1] * self.u[1] + e[2] * self.u[2]) / speed
                self.speed_rate += self.s.speed_rate_gain * along / interval
        self.velocity_t_ns = max(sample.t_ns, self.velocity_t_ns or sample.t_ns)

    def on_airspeed(self, sample: AirspeedSample) -> None:
        self.counts["airspeed_samples"] += 1
        v = sample.airspeed_m_s
        if self.airspeed is not None and self.airspeed_t_ns is not None:
            dt = (sample.t_ns - self.airspeed_t_ns) * _NS
            if dt > 0.0:
                k = min(1.0, dt / self.s.airspeed_rate_tau_s)
                self.airspeed_rate += k * ((v - self.airspeed) / dt - self.airspeed_rate)
        self.airspeed, self.airspeed_t_ns = v, sample.t_ns

    # -- per gyro step ----------------------------------------------------------------------

    def step(self, t_ns: int | None, q: Quat | None, gyro_rad_s: Vec, dt_s: float) -> Vec:
        """Kinematic acceleration (body axes, m/s^2) at this gyro step; ``q`` is the current
        body -> NED estimate (None before the filter has one). Propagates the observer."""
        if not self.s.turn_compensation:
            self.source = "off"
            return _ZERO
        if self.u is not None and q is not None and self._fresh(self.velocity_t_ns, t_ns):
            self.source = "velocity"
            self.counts["compensated_steps"] += 1
            return self._velocity_step(t_ns, q, gyro_rad_s, dt_s)
        if self.u is not None and not self._fresh(self.velocity_t_ns, t_ns):
            self.u = None  # the source stopped: start over when it comes back
        if self.airspeed is not None and self._fresh(self.airspeed_t_ns, t_ns):
            self.source = "airspeed"
            self.counts["compensated_steps"] += 1
            return _along_x(gyro_rad_s, self.airspeed, self.airspeed_rate)
        if self.s.nominal_airspeed_m_s is not None:
            self.source = "nominal"
            self.counts["compensated_steps"] += 1
            return _along_x(gyro_rad_s, self.s.nominal_airspeed_m_s, 0.0)
        self.source = "none"
        return _ZERO

    def _velocity_step(self, t_ns: int | None, q: Quat, gyro_rad_s: Vec, dt_s: float) -> Vec:
        assert self.u is not None
        omega = to_global(q, gyro_rad_s)
        u = self.u
        speed = norm3(u)
        a = cross(omega, u)
        if speed > 1.0:
            k = self.speed_rate / speed
            a = (a[0] + k * u[0], a[1] + k * u[1], a[2] + k * u[2])
        self.u = (u[0] + a[0] * dt_s, u[1] + a[1] * dt_s, u[2] + a[2] * dt_s)
        if t_ns is not None:
            self._history.append((t_ns, self.u))
            while self._history and (t_ns - self._history[0][0]) * _NS > _HISTORY_S:
                self._history.popleft()
        return to_local(q, a)

    def _u_at(self, t_ns: int) -> Vec:
        """The propagated airspeed vector at ``t_ns`` (a velocity sample's epoch)."""
        assert self.u is not None
        best = self.u
        for t, u in reversed(self._history):
            best = u
            if t <= t_ns:
                break
        return best

    def _fresh(self, sample_t_ns: int | None, now_ns: int | None) -> bool:
        if sample_t_ns is None:
            return False
        if now_ns is None:
            return True
        return (now_ns - sample_t_ns) * _NS <= self.s.speed_max_age_s

    # -- state ------------------------------------------------------------------------------

    def as_dict(self) -> dict[str, Any]:
        return {
            "u": None if self.u is None else list(self.u), "wind": list(self.wind),
            "speed_rate": self.speed_rate, "velocity_t_ns": self.velocity_t_ns,
            "airspeed": self.airspeed, "airspeed_t_ns": self.airspeed_t_ns,
            "airspeed_rate": self.airspeed_rate, "counts": dict(self.counts),
        }

    def load_dict(self, d: dict[str, Any]) -> None:
        self.u = None if d["u"] is None else _vec(d["u"])
        self.wind = _vec(d["wind"])
        self.speed_rate = float(d["speed_rate"])
        self.velocity_t_ns = d["velocity_t_ns"]
        self.airspeed = d["airspeed"]
        self.airspeed_t_ns = d["airspeed_t_ns"]
        self.airspeed_rate = float(d["airspeed_rate"])
        self.counts = {k: int(v) for k, v in d["counts"].items()}
        self._history.clear()


def _vec(v: Any) -> Vec:
    return (float(v[0]), float(v[1]), float(v[2]))


def _along_x(gyro_rad_s: Vec, speed_m_s: float, speed_rate_m_s2: float) -> Vec:
    """omega x (V, 0, 0) + (V', 0, 0): a body moving along its own x axis."""
    _, q, r = gyro_rad_s
    return (speed_rate_m_s2, r * speed_m_s, -q * speed_m_s)


def compensated(specific_force_m_s2: Vec, kinematic_m_s2: Vec) -> Vec:
    """The specific force with the kinematic acceleration removed: what gravity alone gives."""
    f, a = specific_force_m_s2, kinematic_m_s2
    return (f[0] - a[0], f[1] - a[1], f[2] - a[2])
