"""Shared helpers for the simulator tests: an independent strapdown integrator."""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import pytest

from imuhal.sim.motion import Kinematics


@dataclass
class ConsistencyErrors:
    attitude_rad: float
    """Largest angle between the integrated and the true attitude."""
    velocity_m_s: float
    position_m: float


def _qmul(p, q):
    pw, px, py, pz = p
    qw, qx, qy, qz = q
    return (pw * qw - px * qx - py * qy - pz * qz, pw * qx + px * qw + py * qz - pz * qy,
            pw * qy - px * qz + py * qw + pz * qx, pw * qz + px * qy - py * qx + pz * qw)


def _qdot(q, w):
    d = _qmul(q, (0.0, w[0], w[1], w[2]))
    return tuple(0.5 * c for c in d)


def _angle_between(a, b) -> float:
    dot = abs(sum(x * y for x, y in zip(a, b, strict=True)))
    return 2.0 * math.acos(min(1.0, dot / math.sqrt(sum(x * x for x in a))))


def _accel_ned(k: Kinematics, g: float):
    """Specific force rotated to NED plus gravity: what an ideal INS integrates."""
    r, f = k.rotation, k.specific_force_body_m_s2
    return (r[0] * f[0] + r[1] * f[1] + r[2] * f[2],
            r[3] * f[0] + r[4] * f[1] + r[5] * f[2],
            r[6] * f[0] + r[7] * f[1] + r[8] * f[2] + g)


def integrate_and_compare(kin: Callable[[float], Kinematics], t_end: float, h: float,
                          gravity: float, t_start: float = 0.0) -> ConsistencyErrors:
    """RK4-integrate the body rate to attitude and (R f + g) to velocity and position from
    the true initial state, comparing with the truth at every step."""
    k0 = kin(t_start)
    q = k0.q_body_to_ned
    v = list(k0.velocity_ned_m_s)
    p = list(k0.position_ned_m)
    err_q = err_v = err_p = 0.0
    n = round((t_end - t_start) / h)
    for j in range(n):
        t = t_start + j * h
        km, k1 = kin(t + h / 2), kin(min(t_start + (j + 1) * h, t_end))
        w0, wm, w1 = (k0.angular_rate_body_rad_s, km.angular_rate_body_rad_s,
                      k1.angular_rate_body_rad_s)
        d1 = _qdot(q, w0)
        d2 = _qdot(tuple(q[i] + h / 2 * d1[i] for i in range(4)), wm)
        d3 = _qdot(tuple(q[i] + h / 2 * d2[i] for i in range(4)), wm)
        d4 = _qdot(tuple(q[i] + h * d3[i] for i in range(4)), w1)
        q = tuple(q[i] + h / 6 * (d1[i] + 2 * d2[i] + 2 * d3[i] + d4[i]) for i in range(4))
        nq = math.sqrt(sum(c * c for c in q))
        q = tuple(c / nq for c in q)
        a0, am, a1 = (_accel_ned(k0, gravity), _accel_ned(km, gravity),
                      _accel_ned(k1, gravity))
        for i in range(3):
            p[i] += h * v[i] + h * h / 6 * (a0[i] + 2 * am[i])
            v[i] += h / 6 * (a0[i] + 4 * am[i] + a1[i])
        k0 = k1
        err_q = max(err_q, _angle_between(q, k1.q_body_to_ned))
        err_v = max(err_v, max(abs(v[i] - k1.velocity_ned_m_s[i]) for i in range(3)))
        err_p = max(err_p, max(abs(p[i] - k1.position_ned_m[i]) for i in range(3)))
    return ConsistencyErrors(err_q, err_v, err_p)


@pytest.fixture
def consistency():
    """``consistency(kin, t_end, h, gravity)`` -> ConsistencyErrors."""
    return integrate_and_compare
