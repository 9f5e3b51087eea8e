"""Initial alignment: the attitude a board at rest shows from one accel (and mag) sample.

A filter started at the identity quaternion needs about pi / gain seconds to find a tilted
board (madgwick at beta 0.1, rolled 170 deg: 32 s) and never finds an exactly upside-down one
(the gradient vanishes there). Starting from the first accelerometer sample instead puts the
tilt right at once: the body-frame gravity direction is the third row of R(body -> NED).
With a magnetometer sample the heading follows from the tilt-compensated field (magnetic
north: the horizontal part of the field); without one, heading is that of the body x axis
(yaw 0) as the 6-DOF references start.
"""

from __future__ import annotations

from imuhal_filters.common.quat import Quat, Vec, cross, norm3

_MIN_NORM = 1e-9


def _unit(v: Vec) -> Vec | None:
    n = norm3(v)
    if not n > _MIN_NORM:
        return None
    return (v[0] / n, v[1] / n, v[2] / n)


def aligned_quaternion(accel_g: Vec, mag: Vec | None = None) -> Quat | None:
    """Body -> NED quaternion from a gravity-positive accelerometer reading (any unit; level
    at rest (0, 0, +1)) and optionally a magnetometer reading (any unit), both body axes.

    Returns None for a zero or non-finite accelerometer vector. A magnetometer vector parallel
    to gravity (or missing) gives yaw 0 (body x projected on the horizontal points north).
    """
    down = _unit(accel_g)
    if down is None:
        return None
    east = None if mag is None else _unit(cross(down, mag))
    if east is None:
        # heading of the body x axis (or, pitched +-90 deg, of the body z axis)
        east = _unit(cross(down, (1.0, 0.0, 0.0))) or _unit(cross(down, (0.0, 0.0, 1.0)))
        assert east is not None
    north = cross(east, down)
    # rows of R(body -> NED) are the NED axes in body coordinates
    return _quat_from_rows(north, east, down)


def _quat_from_rows(n: Vec, e: Vec, d: Vec) -> Quat:
    """Unit quaternion (w >= 0) of the rotation matrix with rows n, e, d (Shepperd)."""
    m00, m01, m02 = n
    m10, m11, m12 = e
    m20, m21, m22 = d
    tr = m00 + m11 + m22
    if tr > 0.0:
        s = 2.0 * (tr + 1.0) ** 0.5
        q = (0.25 * s, (m21 - m12) / s, (m02 - m20) / s, (m10 - m01) / s)
    elif m00 > m11 and m00 > m22:
        s = 2.0 * (1.0 + m00 - m11 - m22) ** 0.5
        q = ((m21 - m12) / s, 0.25 * s, (m01 + m10) / s, (m02 + m20) / s)
    elif m11 > m22:
        s = 2.0 * (1.0 + m11 - m00 - m22) ** 0.5
        q = ((m02 - m20) / s, (m01 + m10) / s, 0.25 * s, (m12 + m21) / s)
    else:
        s = 2.0 * (1.0 + m22 - m00 - m11) ** 0.5
        q = ((m10 - m01) / s, (m02 + m20) / s, (m12 + m21) / s, 0.25 * s)
    n2 = (q[0] ** 2 + q[1] ** 2 + q[2] ** 2 + q[3] ** 2) ** 0.5
    sign = 1.0 if q[0] >= 0.0 else -1.0
    return (sign * q[0] / n2, sign * q[1] / n2, sign * q[2] / n2, sign * q[3] / n2)
