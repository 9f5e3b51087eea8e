"""The three coordinate systems of the Freescale fusion library and their orientation math.

Conventions (those of the reference, kept inside this package):

* ``R`` is the Freescale orientation matrix: it transforms a vector from the *global* frame
  to the *sensor* frame, so its columns are the global axes written in sensor axes
  (``R[:, 2]`` is the global z axis seen by the sensor). ``R`` is the transpose of the usual
  sensor -> global matrix.
* The Freescale quaternion ``q`` (scalar first) rotates sensor -> global:
  ``v_global = q v_sensor q*``, i.e. ``R = quat_to_matrix(q).T``.
* Accelerometer readings are in g with the sign convention of the coordinate system:
  Aerospace/NED and Windows 8 are *gravity positive* (a level board at rest reads +1 g along
  the axis pointing down, i.e. the reading is minus the specific force); Android is
  *acceleration positive* (the reading is the specific force).

Axes:

===========  ==================  ========================  ==================
system       global frame        sensor frame (x, y, z)    level reading
===========  ==================  ========================  ==================
NED          north, east, down   forward, right, down      accel (0, 0, +1) g
ANDROID      east, north, up     right, forward, up        accel (0, 0, +1) g
WIN8         east, north, up     right, forward, up        accel (0, 0, -1) g
===========  ==================  ========================  ==================

The Android/Windows 8 frames are the NED ones with x and y swapped and z negated, in both the
sensor and the global frame (a proper rotation: 180 deg about the north-east diagonal). These
are the core conventions ``aerospace``, ``android`` and ``win8`` (imuhal.core.conventions),
whose exact conversions hand NED body data to a filter and turn its orientation back into a
body -> NED quaternion.
"""

from __future__ import annotations

import math
from enum import Enum

import numpy as np

from imuhal.core.conventions import (
    AEROSPACE,
    ANDROID,
    NED,
    WIN8,
    VectorKind,
    convert_quat,
    euler_deg_from_quat,
    vector_from_ned,
)
from imuhal.core.frames import FloatArray, quat_from_matrix, quat_to_matrix

DEG = math.pi / 180.0
"""Degrees -> radians (the reference's FDEGTORAD)."""


class CoordinateSystem(str, Enum):
    """Coordinate system of the reference build (``THISCOORDSYSTEM`` in build.h)."""

    NED = "ned"
    """Aerospace: global north-east-down, sensor forward-right-down, gravity positive."""
    ANDROID = "android"
    """Android: global east-north-up, sensor right-forward-up, acceleration positive."""
    WIN8 = "win8"
    """Windows 8: global east-north-up, sensor right-forward-up, gravity positive."""

    @property
    def gravity_positive(self) -> bool:
        """True where a level board at rest reads +1 g *along the down direction*."""
        return self is not CoordinateSystem.ANDROID


# ---------------------------------------------------------------------------------------------
# quaternions and rotation vectors (Freescale convention: q rotates sensor -> global)


def matrix_from_quat(q: FloatArray) -> FloatArray:
    """Freescale orientation matrix R (global -> sensor) of the sensor -> global quaternion."""
    return quat_to_matrix(q).T


def quat_from_matrix_fsl(r: FloatArray) -> FloatArray:
    """Sensor -> global quaternion (scalar >= 0) of a Freescale matrix R (global -> sensor)."""
    return quat_from_matrix(np.asarray(r).T)


def quat_from_rotvec_deg(rvec_deg: FloatArray) -> FloatArray:
    """Quaternion of a rotation vector in degrees (axis times angle), scalar >= 0.

    The reference evaluates sin(eta/2) by a truncated series for small angles and takes
    q0 = sqrt(1 - |q_vec|^2); both equal the exact values here to better than 1e-7.
    """
    eta = math.sqrt(float(rvec_deg @ rvec_deg)) * DEG
    if eta == 0.0:
        return np.array([1.0, 0.0, 0.0, 0.0])
    vec = np.asarray(rvec_deg) * DEG * (math.sin(0.5 * eta) / eta)
    return np.array([math.cos(0.5 * eta), *vec])


def quat_mul(p: FloatArray, q: FloatArray) -> FloatArray:
    """Hamilton product p * q of two (w, x, y, z) arrays."""
    pw, px, py, pz = p
    qw, qx, qy, qz = q
    return np.array([
        pw * qw - px * qx - py * qy - pz * qz,
        pw * qx + px * qw + py * qz - pz * qy,
        pw * qy - px * qz + py * qw + pz * qx,
        pw * qz + px * qy - py * qx + pz * qw,
    ])


def normalise_positive(q: FloatArray) -> FloatArray:
    """Unit quaternion with non-negative scalar part; identity if ``q`` is corrupt (|q| tiny)."""
    n = float(np.linalg.norm(q))
    if not n > 1e-3:
        return np.array([1.0, 0.0, 0.0, 0.0])
    out = np.asarray(q, dtype=float) / n
    return -out if out[0] < 0.0 else out


def skew(v: FloatArray) -> FloatArray:
    """Matrix [v]x with [v]x @ u = v x u."""
    x, y, z = v
    return np.array([[0.0, -z, y], [z, 0.0, -x], [-y, x, 0.0]])


# ---------------------------------------------------------------------------------------------
# accelerometer tilt (the 6DOF filter's start) and eCompass (the 9DOF filter's start)


def tilt_matrix(cs: CoordinateSystem, accel_g: FloatArray) -> FloatArray:
    """Orientation R from the accelerometer alone, with the reference's zero-yaw choice.

    NED and Android: the global y axis has no sensor-x component. Windows 8: the global x
    axis has no sensor-y component (both mean "heading zero" for the board's forward axis).
    """
    g = np.asarray(accel_g, dtype=float)
    if cs is CoordinateSystem.WIN8:
        return _tilt_win8(g)
    return _tilt_ned(g)


def _tilt_ned(g: FloatArray) -> FloatArray:
    gyz2 = g[1] ** 2 + g[2] ** 2
    gxyz2 = gyz2 + g[0] ** 2
    if gxyz2 == 0.0:
        return np.eye(3)
    r = np.zeros((3, 3))
    if gyz2 == 0.0:  # gravity along sensor x: pitched by 90 degrees
        sign = 1.0 if g[0] >= 0.0 else -1.0
        r[1, 1] = 1.0
        r[0, 2], r[2, 0] = sign, -sign
        return r
    gyz, gxyz = math.sqrt(gyz2), math.sqrt(gxyz2)
    ratio = gxyz / gyz
    r[:, 2] = g / gxyz
    r[0, 0] = gyz / gxyz
    r[1, 0] = -r[0, 2] * r[1, 2] * ratio
    r[2, 0] = -r[0, 2] * r[2, 2] * ratio
    r[1, 1] = r[2, 2] * ratio
    r[2, 1] = -r[1, 2] * ratio
    return r


def _tilt_win8(g: FloatArray) -> FloatArray:
    gxz2 = g[0] ** 2 + g[2] ** 2
    gxyz2 = gxz2 + g[1] ** 2
    if gxyz2 == 0.0:
        return np.eye(3)
    r = np.zeros((3, 3))
    if gxz2 == 0.0:  # gravity along sensor y
        sign = 1.0 if g[1] >= 0.0 else -1.0
        r[0, 0] = 1.0
        r[1, 2], r[2, 1] = -sign, sign
        return r
    gxz, gxyz = math.sqrt(gxz2), math.sqrt(gxyz2)
    # the sign flip keeps the solution continuous when the board is upside down
    ratio = gxyz / gxz * (-1.0 if g[2] < 0.0 else 1.0)
    r[:, 2] = -g / gxyz
    r[0, 0] = -r[2, 2] * ratio
    r[2, 0] = r[0, 2] * ratio
    r[0, 1] = r[0, 2] * r[1, 2] * ratio
    r[1, 1] = -gxz / gxyz * (-1.0 if g[2] < 0.0 else 1.0)
    r[2, 1] = r[1, 2] * r[2, 2] * ratio
    return r


def ecompass(cs: CoordinateSystem, accel_g: FloatArray,
             mag_ut: FloatArray) -> tuple[FloatArray, float]:
    """Orientation R and inclination (deg) from one accelerometer and magnetometer reading.

    The down (NED) or up (Android, Windows 8) column comes from the accelerometer, the
    east/north columns from cross products with the magnetic field. Returns the identity and
    zero inclination when either vector is zero or they are parallel.
    """
    g = np.asarray(accel_g, dtype=float)
    b = np.asarray(mag_ut, dtype=float)
    r = np.zeros((3, 3))
    if cs is CoordinateSystem.NED:
        down = g
        east = np.cross(down, b)
        north = np.cross(east, down)
        r[:, 0], r[:, 1], r[:, 2] = north, east, down
        sign = 1.0
    else:
        up = g if cs is CoordinateSystem.ANDROID else -g
        east = np.cross(b, up)
        north = np.cross(up, east)
        r[:, 0], r[:, 1], r[:, 2] = east, north, up
        sign = -1.0 if cs is CoordinateSystem.ANDROID else 1.0
    norms = np.linalg.norm(r, axis=0)
    if np.any(norms == 0.0):
        return np.eye(3), 0.0
    r /= norms
    bnorm = float(np.linalg.norm(b))
    if bnorm == 0.0:
        return r, 0.0
    # the reference measures the inclination against the *signed* accelerometer reading, so
    # Android (acceleration positive) needs the minus sign to report the dip as positive
    s = sign * float(g @ b) / (float(np.linalg.norm(g)) * bnorm)
    return r, _asin_deg(s)


# ---------------------------------------------------------------------------------------------
# Euler angles in each system's own convention


def _acos_deg(x: float) -> float:
    return math.degrees(math.acos(max(-1.0, min(1.0, x))))


def _asin_deg(x: float) -> float:
    return math.degrees(math.asin(max(-1.0, min(1.0, x))))


CONVENTION = {CoordinateSystem.NED: AEROSPACE, CoordinateSystem.ANDROID: ANDROID,
               CoordinateSystem.WIN8: WIN8}
"""The core convention each build's axes, accelerometer sign and Euler angles are."""


def euler_angles_deg(cs: CoordinateSystem, r: FloatArray) -> dict[str, float]:
    """The reference's Euler angles of R: roll ``phi``, pitch ``theta``, yaw ``psi`` (0..360),
    compass heading ``rho`` and tilt from level ``chi`` (all degrees).

    Each coordinate system has its own rotation sequence and signs (NED: aerospace ZYX, yaw
    clockwise from north; Android: roll about y and pitch about x; Windows 8: pitch about x
    from -180 to 180 and roll about y from -90 to 90, heading anticlockwise); the definitions
    live in ``imuhal.core.conventions`` (styles freescale_ned / _android / _win8).
    """
    phi, theta, psi = euler_deg_from_quat(CONVENTION[cs], quat_from_matrix_fsl(r))
    rho = _wrap_360(360.0 - psi) if cs is CoordinateSystem.WIN8 else psi
    return {"phi": phi, "theta": theta, "psi": psi, "rho": rho, "chi": _acos_deg(r[2, 2])}


def _wrap_360(a: float) -> float:
    a = a + 360.0 if a < 0.0 else a
    return 0.0 if a >= 360.0 else a


# ---------------------------------------------------------------------------------------------
# boundary: NED body data in, body -> NED quaternion out


def to_sensor_vector(cs: CoordinateSystem, v_body_ned: FloatArray) -> FloatArray:
    """A body-NED (forward, right, down) vector in the sensor axes of ``cs``."""
    return vector_from_ned(v_body_ned, CONVENTION[cs], VectorKind.ANGULAR_RATE)


SignedAxes = tuple[tuple[int, float], tuple[int, float], tuple[int, float]]
"""Per sensor axis: (index of the body NED component, sign). Every convention's body axes are
a signed permutation of NED's, so a sample's vector converts on plain floats, exactly."""


def sensor_axes(cs: CoordinateSystem, *, specific_force: bool = False) -> SignedAxes:
    """:func:`to_sensor_vector` (or, with ``specific_force``, :func:`accel_reading_g`) as a
    signed permutation: ``out[i] = sign * v[index]``, the same floats without numpy."""
    c = CONVENTION[cs]
    m = c.body_from_frd.T  # vector_from_ned computes v @ M.T
    factor = c.accel_sign.factor if specific_force else 1.0
    axes = []
    for i in range(3):
        (k,) = np.flatnonzero(m[:, i])
        axes.append((int(k), float(m[k, i]) * factor))
    return (axes[0], axes[1], axes[2])


def accel_reading_g(cs: CoordinateSystem, specific_force_body_ned_g: FloatArray) -> FloatArray:
    """The accelerometer reading ``cs`` expects (g, its axes and sign) from specific force."""
    return vector_from_ned(specific_force_body_ned_g, CONVENTION[cs], VectorKind.SPECIFIC_FORCE)


def quat_body_to_ned(cs: CoordinateSystem, q_fsl: FloatArray) -> FloatArray:
    """Body -> NED quaternion (scalar >= 0) from the filter's sensor -> global quaternion."""
    return normalise_positive(convert_quat(q_fsl, CONVENTION[cs], NED))
