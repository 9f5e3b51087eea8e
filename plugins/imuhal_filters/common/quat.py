"""Plain-float quaternion helpers for the per-step AHRS kernels.

The kernels run once per gyro sample in pure Python, where tuples of floats are several times
faster than small numpy arrays. Quaternions are (w, x, y, z), Hamilton, and rotate body -> NED
(``v_ned = q v_body q*``), the same convention as :mod:`imuhal.core.frames`.
"""

from __future__ import annotations

import math
from typing import TypeAlias

Quat: TypeAlias = tuple[float, float, float, float]
Vec: TypeAlias = tuple[float, float, float]

IDENTITY: Quat = (1.0, 0.0, 0.0, 0.0)


def normalized(q: Quat) -> Quat:
    """``q / |q|``; raises ValueError for a zero or non-finite quaternion."""
    n = math.sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3])
    if n == 0.0 or not math.isfinite(n):
        raise ValueError(f"cannot normalise quaternion {q}")
    inv = 1.0 / n
    return (q[0] * inv, q[1] * inv, q[2] * inv, q[3] * inv)


def multiply(p: Quat, q: Quat) -> Quat:
    """Hamilton product p * q."""
    pw, px, py, pz = p
    qw, qx, qy, qz = q
    return (
        pw * qw - px * qx - py * qy - pz * qz,
        pw * qx + px * qw + py * qz - pz * qy,
        pw * qy - px * qz + py * qw + pz * qx,
        pw * qz + px * qy - py * qx + pz * qw,
    )


def rate_derivative(q: Quat, w: Vec) -> Quat:
    """dq/dt = 0.5 q * (0, w) for a body angular rate ``w`` (rad/s)."""
    q0, q1, q2, q3 = q
    gx, gy, gz = w
    return (
        0.5 * (-q1 * gx - q2 * gy - q3 * gz),
        0.5 * (q0 * gx + q2 * gz - q3 * gy),
        0.5 * (q0 * gy - q1 * gz + q3 * gx),
        0.5 * (q0 * gz + q1 * gy - q2 * gx),
    )


def to_global(q: Quat, v: Vec) -> Vec:
    """Rotate a body-frame vector into the global (NED) frame: q v q*."""
    w, x, y, z = q
    vx, vy, vz = v
    # t = 2 (u x v); v' = v + w t + u x t  (u = vector part), valid for unit q
    tx = 2.0 * (y * vz - z * vy)
    ty = 2.0 * (z * vx - x * vz)
    tz = 2.0 * (x * vy - y * vx)
    return (
        vx + w * tx + (y * tz - z * ty),
        vy + w * ty + (z * tx - x * tz),
        vz + w * tz + (x * ty - y * tx),
    )


def to_local(q: Quat, v: Vec) -> Vec:
    """Rotate a global (NED) vector into the body frame: q* v q."""
    return to_global((q[0], -q[1], -q[2], -q[3]), v)


def norm3(v: Vec) -> float:
    return math.sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2])


def cross(a: Vec, b: Vec) -> Vec:
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


def dot(a: Vec, b: Vec) -> float:
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


def angle_between_deg(p: Quat, q: Quat) -> float:
    """Rotation angle (deg) of p^-1 q: the attitude error between two unit quaternions."""
    d = abs(p[0] * q[0] + p[1] * q[1] + p[2] * q[2] + p[3] * q[3])
    return math.degrees(2.0 * math.acos(min(1.0, d)))


def tilt_error_deg(p: Quat, q: Quat) -> float:
    """Angle (deg) between the NED down axes of two attitudes, seen in the body: heading-free."""
    dp = to_local(p, (0.0, 0.0, 1.0))
    dq = to_local(q, (0.0, 0.0, 1.0))
    c = max(-1.0, min(1.0, dot(dp, dq) / (norm3(dp) * norm3(dq))))
    return math.degrees(math.acos(c))
