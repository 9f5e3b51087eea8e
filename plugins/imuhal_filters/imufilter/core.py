"""RCmags imuFilter (v1.6.3) as pure per-step functions (plain floats, float64).

Frame convention. The library keeps a quaternion q with ``q a q* = (0, 0, 1)`` for the
accelerometer reading ``a`` of a board at rest, and integrates ``q <- q * dq(gyro dt)``. Fed
the gravity-positive accelerometer (level at rest: (0, 0, +1) g) in body NED axes, that q is
exactly a body -> NED quaternion, with heading 0 at setup (6-DOF: yaw is relative).

The library's ``rotate(v, flag)`` / ``axisX(flag)`` take a flag it calls TO_GLOBAL, but the
value that takes a vector to the global frame is its ``GLOBAL_FRAME = false``. Here the two
directions have their own names: :func:`to_global` (body -> NED) and :func:`to_local`.
"""

from __future__ import annotations

import math

from imuhal_filters.common.quat import (
    Quat,
    Vec,
    cross,
    dot,
    multiply,
    normalized,
    to_global,
    to_local,
)

DOWN: Vec = (0.0, 0.0, 1.0)


def setup_quaternion(accel_g: Vec) -> Quat:
    """The library's ``setup(ax, ay, az)``: the tilt that maps ``accel_g`` onto +z, yaw 0.

    The library divides by ``ax^2 + ay^2`` and returns NaN for an exactly level (or exactly
    inverted) reading; this port returns the identity (or a half turn about x) there.
    """
    n = math.sqrt(dot(accel_g, accel_g))
    if n == 0.0 or not math.isfinite(n):
        raise ValueError(f"cannot set the attitude up from accelerometer {accel_g}")
    vx, vy, vz = accel_g[0] / n, accel_g[1] / n, accel_g[2] / n
    nxy = vx * vx + vy * vy
    if nxy == 0.0:
        return (1.0, 0.0, 0.0, 0.0) if vz > 0.0 else (0.0, 1.0, 0.0, 0.0)
    cosine = 0.5 * vz / math.sqrt(nxy + vz * vz)  # half the cosine of the tilt
    s = math.sqrt((0.5 - cosine) / nxy)  # sine of the half angle, over |v_xy|
    return (math.sqrt(0.5 + cosine), vy * s, -vx * s, 0.0)


def _small_rotation(da: Vec) -> Quat:
    """The library's ``setRotation(da, SMALL_ANGLE)``: v = da / 2, w = 1 - |v|^2 / 2."""
    vx, vy, vz = 0.5 * da[0], 0.5 * da[1], 0.5 * da[2]
    return (1.0 - 0.5 * (vx * vx + vy * vy + vz * vz), vx, vy, vz)


def gyro_step(q: Quat, gyro_rad_s: Vec, dt_s: float) -> Quat:
    """``update(gx, gy, gz)``: integrate the gyro alone."""
    da = (gyro_rad_s[0] * dt_s, gyro_rad_s[1] * dt_s, gyro_rad_s[2] * dt_s)
    return normalized(multiply(q, _small_rotation(da)))


def accel_kalman_gain(q: Quat, var: float, accel_g: Vec, sd_acc_g: float) -> tuple[float, float]:
    """The band check: (gain in 0..1, new variance g^2) from the deviation of the rotated
    accelerometer from (0, 0, 1) g. Inside the band the gain stays near 1; a sustained
    deviation grows the variance and the gain falls, so the correction barely acts."""
    ax, ay, az = to_global(q, accel_g)
    az -= 1.0
    error = ax * ax + ay * ay + az * az
    gain = 1.0 / (1.0 + var / (sd_acc_g * sd_acc_g))
    return gain, error + var * gain


def imufilter_step(
    q: Quat, var: float, gyro_rad_s: Vec, accel_g: Vec, dt_s: float, alpha: float,
    sd_acc_g: float, *, at_rest: bool = False,
) -> tuple[Quat, float, float]:
    """``update(gx, gy, gz, ax, ay, az, ALPHA, SD_ACC)``; returns (q, variance, gain).

    The correction turns the body's estimate of "down" towards the accelerometer at the rate
    ``gain * alpha`` (rad/s per unit sine of the error): ``alpha`` is the library's gain/delay
    parameter, a first-order low pass on the accelerometer. ``at_rest`` (the board known to
    be still, common/rest.py; not in the library): the reading is gravity, so the correction
    runs at gain 1 (the returned gain); the band's variance is kept as the library keeps it.
    """
    gain, var = accel_kalman_gain(q, var, accel_g, sd_acc_g)
    if at_rest:
        gain = 1.0
    n = math.sqrt(dot(accel_g, accel_g))
    a_unit = (accel_g[0] / n, accel_g[1] / n, accel_g[2] / n)
    ve = cross(a_unit, to_local(q, DOWN))  # error about the vertical, body axes
    k = gain * alpha * dt_s
    da = (gyro_rad_s[0] * dt_s + ve[0] * k, gyro_rad_s[1] * dt_s + ve[1] * k,
          gyro_rad_s[2] * dt_s + ve[2] * k)
    return normalized(multiply(q, _small_rotation(da))), var, gain


def rotate_heading(q: Quat, angle_rad: float, *, small_angle: bool = False) -> Quat:
    """``rotateHeading``: turn the attitude by ``angle_rad`` about the vertical (yaw += angle).

    ``small_angle`` uses the library's approximation (w = 1 - (angle/2)^2); the library then
    leaves q unnormalised, this port normalises it.
    """
    vp = to_local(q, DOWN)
    h = 0.5 * angle_rad
    if small_angle:
        w, s = 1.0 - h * h, h
    else:
        w, s = math.cos(h), math.sin(h)
    return normalized(multiply(q, (w, s * vp[0], s * vp[1], s * vp[2])))


def axis_unit_vectors(q: Quat, *, in_global: bool) -> tuple[Vec, Vec, Vec]:
    """The x, y, z axes of one frame expressed in the other.

    ``in_global=True``: the body axes in NED (the columns of R); ``False``: the NED axes in
    body coordinates (the rows of R; the library's ``getXaxis(true)`` etc.).
    """
    f = to_global if in_global else to_local
    return f(q, (1.0, 0.0, 0.0)), f(q, (0.0, 1.0, 0.0)), f(q, (0.0, 0.0, 1.0))
