"""imuFilter's velocity estimate (its ``accIntegral``), ported to project units (NED, m/s).

Per step, after the attitude update:

1. the library's centrifugal correction ``f - v_body x w`` is applied to the specific force,
   which is rotated to NED and gravity added back: the linear acceleration ``a`` (m/s^2);
2. rest-condition band: a running mean of ``a`` is tracked with the Kalman-like gain
   ``sd_acc^2 / (sd_acc^2 + var_acc)`` and subtracted. Small or steady deviations from rest
   (bias, miscalibration, a residual of gravity) fall into the mean and are suppressed; large
   fluctuating accelerations raise ``var_acc`` so the mean stops following them;
3. the velocity is pulled towards a target (usually 0) with the gain
   ``sd_acc^2 sd_vel^2 / (sd_acc^2 sd_vel^2 + var_vel var_acc)``: strong when both the velocity
   change and the acceleration are small;
4. the filtered acceleration is integrated with the trapezoidal rule.

The library works in g and g*s; every gain above is a ratio of variances, so the same filter
in m/s^2 and m/s gives the same velocity times g.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from imuhal.core.atmosphere import STANDARD_GRAVITY_M_S2
from imuhal_filters.common.quat import Quat, Vec, cross, dot, to_global, to_local

ZERO: Vec = (0.0, 0.0, 0.0)


@dataclass(slots=True)
class VelocityState:
    """All in NED: velocity m/s, accelerations m/s^2, variances (m/s)^2 and (m/s^2)^2."""

    velocity: Vec = ZERO
    accel_mean: Vec = ZERO
    accel_last: Vec = ZERO
    var_vel: float = 0.0
    var_acc: float = 0.0

    def to_dict(self) -> dict[str, Any]:
        return {"velocity": list(self.velocity), "accel_mean": list(self.accel_mean),
                "accel_last": list(self.accel_last), "var_vel": self.var_vel,
                "var_acc": self.var_acc}

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> VelocityState:
        def v(k: str) -> Vec:
            x, y, z = (float(c) for c in d[k])
            return (x, y, z)

        return cls(v("velocity"), v("accel_mean"), v("accel_last"), float(d["var_vel"]),
                   float(d["var_acc"]))


def velocity_step(
    state: VelocityState,
    q: Quat,
    gyro_rad_s: Vec,
    specific_force_m_s2: Vec,
    dt_s: float,
    sd_acc_m_s2: float,
    sd_vel_m_s: float,
    target_ned_m_s: Vec = ZERO,
) -> VelocityState:
    """One ``accIntegral::update`` after the attitude step that produced ``q``."""
    var_a = sd_acc_m_s2 * sd_acc_m_s2
    var_comb = var_a * sd_vel_m_s * sd_vel_m_s
    v = state.velocity
    c = cross(to_local(q, v), gyro_rad_s)
    f = (specific_force_m_s2[0] - c[0], specific_force_m_s2[1] - c[1],
         specific_force_m_s2[2] - c[2])
    ax, ay, az = to_global(q, f)
    m = state.accel_mean
    a = (ax - m[0], ay - m[1], az + STANDARD_GRAVITY_M_S2 - m[2])
    gain_acc = var_a / (var_a + state.var_acc)
    var_acc = dot(a, a) + gain_acc * state.var_acc
    mean = (m[0] + a[0] * gain_acc, m[1] + a[1] * gain_acc, m[2] + a[2] * gain_acc)
    dv = (target_ned_m_s[0] - v[0], target_ned_m_s[1] - v[1], target_ned_m_s[2] - v[2])
    gain_vel = var_comb / (var_comb + state.var_vel * var_acc)
    var_vel = dot(dv, dv) + gain_vel * state.var_vel
    last = state.accel_last
    h = 0.5 * dt_s
    vel = tuple(v[i] + (a[i] + last[i]) * h + dv[i] * gain_vel for i in range(3))
    return VelocityState((vel[0], vel[1], vel[2]), mean, a, var_vel, var_acc)
