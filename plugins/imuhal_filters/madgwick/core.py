"""Madgwick's gradient-descent AHRS as pure per-step functions (plain floats, float64).

Conventions are those of the x-io C release (MadgwickAHRS.c, 2012-02-19), which the seed uses
unchanged in NED: quaternion (w, x, y, z) rotating body -> NED; gyro in rad/s; the
accelerometer gravity positive (a level board at rest reads (0, 0, +1), any unit, it is
normalised); the magnetometer in any unit (normalised). One step:

    q_dot = 0.5 q * (0, gyro) - beta * s / |s|,   q <- normalise(q + q_dot dt)

where ``s = J^T f`` is the gradient of the squared error between the measured directions and
the directions the attitude predicts: gravity (0, 0, 1) and the earth field (b_x, 0, b_z)
expressed in the body. This module evaluates that gradient from the objective and its
Jacobian rather than from the release's expanded polynomials; the two are algebraically equal.

The magnetometer reference (MagReference):

- ``xio_release``: the release sets its variable ``_2bx = sqrt(hx^2 + hy^2)`` (and likewise
  ``_2bz = hz``) where the paper means 2 b_x and 2 b_z. The predicted field is then half the
  measured one. For a level board the magnetometer gradient is then half the paper's (a
  weaker heading correction); for a tilted board it no longer vanishes at the true attitude
  (about 0.015 at roll -3, pitch 5 deg; 0.14 at roll 40, pitch -30 deg, with unit vectors), so
  the equilibrium the magnetometer pulls towards is off the truth. On data set A (beta 0.1,
  t >= 5 s) this port measures 0.50 deg total / 0.27 deg tilt RMS error for the release form
  against 0.29 / 0.18 deg for the paper form. The conformance vectors and the seed's firmware
  use the release form.
- ``paper`` (the documented correction): ``2 b_x = 2 sqrt(hx^2 + hy^2)``, ``2 b_z = 2 hz``; the
  residual vanishes at the true attitude and every step is a pure rotation of size beta.
"""

from __future__ import annotations

import math
from enum import Enum

from imuhal_filters.common.quat import Quat, Vec, rate_derivative
from imuhal_filters.madgwick.inv_sqrt import InvSqrt, exact_inv_sqrt


class MagReference(str, Enum):
    """How the earth-field reference (b_x, b_z) is formed from the rotated magnetometer."""

    XIO_RELEASE = "xio_release"
    PAPER = "paper"


def accel_gradient(q: Quat, a: Vec) -> tuple[float, float, float, float]:
    """J_g^T f_g for a normalised gravity-positive accelerometer vector ``a``."""
    q0, q1, q2, q3 = q
    f1 = 2.0 * (q1 * q3 - q0 * q2) - a[0]
    f2 = 2.0 * (q0 * q1 + q2 * q3) - a[1]
    f3 = 2.0 * (0.5 - q1 * q1 - q2 * q2) - a[2]
    return (
        -2.0 * q2 * f1 + 2.0 * q1 * f2,
        2.0 * q3 * f1 + 2.0 * q0 * f2 - 4.0 * q1 * f3,
        -2.0 * q0 * f1 + 2.0 * q3 * f2 - 4.0 * q2 * f3,
        2.0 * q1 * f1 + 2.0 * q2 * f2,
    )


def mag_gradient(q: Quat, m: Vec, reference: MagReference) -> tuple[float, float, float, float]:
    """J_b^T f_b for a normalised magnetometer vector ``m``."""
    q0, q1, q2, q3 = q
    mx, my, mz = m
    q00, q11, q22, q33 = q0 * q0, q1 * q1, q2 * q2, q3 * q3
    # earth-frame field h = R(q) m, written as the homogeneous quadratic form so that a
    # slightly non-unit q (fast32 mode) is treated exactly as the release treats it
    hx = (mx * (q00 + q11 - q22 - q33) + 2.0 * my * (q1 * q2 - q0 * q3)
          + 2.0 * mz * (q1 * q3 + q0 * q2))
    hy = (2.0 * mx * (q1 * q2 + q0 * q3) + my * (q00 - q11 + q22 - q33)
          + 2.0 * mz * (q2 * q3 - q0 * q1))
    hz = (2.0 * mx * (q1 * q3 - q0 * q2) + 2.0 * my * (q2 * q3 + q0 * q1)
          + mz * (q00 - q11 - q22 + q33))
    scale = 1.0 if reference is MagReference.XIO_RELEASE else 2.0
    bx2 = scale * math.sqrt(hx * hx + hy * hy)  # "2 b_x"
    bz2 = scale * hz  # "2 b_z"
    f4 = bx2 * (0.5 - q22 - q33) + bz2 * (q1 * q3 - q0 * q2) - mx
    f5 = bx2 * (q1 * q2 - q0 * q3) + bz2 * (q0 * q1 + q2 * q3) - my
    f6 = bx2 * (q0 * q2 + q1 * q3) + bz2 * (0.5 - q11 - q22) - mz
    return (
        -bz2 * q2 * f4 + (-bx2 * q3 + bz2 * q1) * f5 + bx2 * q2 * f6,
        bz2 * q3 * f4 + (bx2 * q2 + bz2 * q0) * f5 + (bx2 * q3 - 2.0 * bz2 * q1) * f6,
        (-2.0 * bx2 * q2 - bz2 * q0) * f4 + (bx2 * q1 + bz2 * q3) * f5
        + (bx2 * q0 - 2.0 * bz2 * q2) * f6,
        (-2.0 * bx2 * q3 + bz2 * q1) * f4 + (-bx2 * q0 + bz2 * q2) * f5 + bx2 * q1 * f6,
    )


def _unit3(v: Vec, inv_sqrt: InvSqrt) -> Vec | None:
    n2 = v[0] * v[0] + v[1] * v[1] + v[2] * v[2]
    if n2 == 0.0:  # the release skips an all-zero vector ("handle NaN")
        return None
    r = inv_sqrt(n2)
    return (v[0] * r, v[1] * r, v[2] * r)


def madgwick_step(
    q: Quat,
    gyro_rad_s: Vec,
    accel: Vec | None,
    mag: Vec | None,
    beta: float,
    dt_s: float,
    *,
    mag_reference: MagReference = MagReference.PAPER,
    inv_sqrt: InvSqrt = exact_inv_sqrt,
) -> Quat:
    """One Madgwick step; returns the new quaternion.

    ``accel`` None (or all zero) integrates the gyro only, as the release does; with ``mag``
    None (or all zero) the step is the 6-DOF (IMU) update, otherwise the 9-DOF (MARG) update.
    Gating is the caller's business: pass ``accel=None`` to skip the whole gradient step.
    """
    d0, d1, d2, d3 = rate_derivative(q, gyro_rad_s)
    a = None if accel is None else _unit3(accel, inv_sqrt)
    if a is not None:
        s0, s1, s2, s3 = accel_gradient(q, a)
        m = None if mag is None else _unit3(mag, inv_sqrt)
        if m is not None:
            g0, g1, g2, g3 = mag_gradient(q, m, mag_reference)
            s0, s1, s2, s3 = s0 + g0, s1 + g1, s2 + g2, s3 + g3
        n2 = s0 * s0 + s1 * s1 + s2 * s2 + s3 * s3
        if n2 > 0.0:  # exactly on the minimum there is no direction to step in
            k = beta * inv_sqrt(n2)
            d0, d1, d2, d3 = d0 - k * s0, d1 - k * s1, d2 - k * s2, d3 - k * s3
    w, x, y, z = q[0] + d0 * dt_s, q[1] + d1 * dt_s, q[2] + d2 * dt_s, q[3] + d3 * dt_s
    r = inv_sqrt(w * w + x * x + y * y + z * z)
    return (w * r, x * r, y * r, z * r)
