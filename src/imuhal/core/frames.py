"""Quaternions, Euler angles and mount rotations, in the seed's NED conventions.

Quaternions are numpy arrays ``(w, x, y, z)``, scalar first, Hamilton product, rotating
body -> NED: ``v_ned = q * v_body * q^-1``. Euler angles are aerospace ZYX
(R = Rz(yaw) Ry(pitch) Rx(roll)): yaw in [-180, 180] degrees clockwise from north seen from
above, pitch up positive, roll right positive.
"""

from __future__ import annotations

import math
import re
from collections.abc import Sequence
from typing import Any

import numpy as np
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]
Vector = Sequence[float] | NDArray[np.floating[Any]]
"""A vector or quaternion as numbers or a numpy array (the functions here take either)."""
Matrix = Sequence[Sequence[float]] | NDArray[np.floating[Any]]
"""A matrix as rows of numbers or a numpy array."""

IDENTITY_QUATERNION: FloatArray = np.array([1.0, 0.0, 0.0, 0.0])


def quat_multiply(p: Sequence[float], q: Sequence[float]) -> FloatArray:
    """Hamilton product p * q."""
    pw, px, py, pz = p
    qw, qx, qy, qz = q
    return np.array(
        [
            pw * qw - px * qx - py * qy - pz * qz,
            pw * qx + px * qw + py * qz - pz * qy,
            pw * qy - px * qz + py * qw + pz * qx,
            pw * qz + px * qy - py * qx + pz * qw,
        ]
    )


def quat_normalize(q: Vector) -> FloatArray:
    a = np.asarray(q, dtype=float)
    n = float(np.linalg.norm(a))
    if n == 0.0 or not math.isfinite(n):
        raise ValueError(f"cannot normalise quaternion {list(a)}")
    return a / n


def quat_to_matrix(q: Vector) -> FloatArray:
    """Rotation matrix R with v_ned = R @ v_body for a unit quaternion body -> NED."""
    w, x, y, z = q
    return np.array(
        [
            [w * w + x * x - y * y - z * z, 2 * (x * y - w * z), 2 * (x * z + w * y)],
            [2 * (x * y + w * z), w * w - x * x + y * y - z * z, 2 * (y * z - w * x)],
            [2 * (x * z - w * y), 2 * (y * z + w * x), w * w - x * x - y * y + z * z],
        ]
    )


def quat_rotate(q: Sequence[float], v_body: Sequence[float]) -> FloatArray:
    """Rotate a body-frame vector into NED with the body -> NED quaternion ``q``."""
    rotated: FloatArray = quat_to_matrix(q) @ np.asarray(v_body, dtype=float)
    return rotated


def quat_from_euler_deg(roll_deg: float, pitch_deg: float, yaw_deg: float) -> FloatArray:
    """Body -> NED quaternion from ZYX Euler angles in degrees."""
    r, p, y = (math.radians(a) / 2 for a in (roll_deg, pitch_deg, yaw_deg))
    cr, sr, cp, sp, cy, sy = (math.cos(r), math.sin(r), math.cos(p), math.sin(p),
                              math.cos(y), math.sin(y))
    return np.array(
        [
            cy * cp * cr + sy * sp * sr,
            cy * cp * sr - sy * sp * cr,
            cy * sp * cr + sy * cp * sr,
            sy * cp * cr - cy * sp * sr,
        ]
    )


def euler_deg_from_quat(q: Vector) -> tuple[float, float, float]:
    """(roll, pitch, yaw) in degrees from a body -> NED quaternion; yaw in [-180, 180]."""
    w, x, y, z = quat_normalize(q)
    roll = math.atan2(2 * (w * x + y * z), 1 - 2 * (x * x + y * y))
    sin_pitch = max(-1.0, min(1.0, 2 * (w * y - z * x)))
    pitch = math.asin(sin_pitch)
    yaw = math.atan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))
    return math.degrees(roll), math.degrees(pitch), math.degrees(yaw)


def quat_from_matrix(m: Matrix) -> FloatArray:
    """Unit quaternion (w >= 0) of a proper rotation matrix (Shepperd's method)."""
    a = np.asarray(m, dtype=float)
    tr = float(np.trace(a))
    if tr > 0:
        s = math.sqrt(tr + 1.0) * 2
        q = [0.25 * s, (a[2, 1] - a[1, 2]) / s, (a[0, 2] - a[2, 0]) / s, (a[1, 0] - a[0, 1]) / s]
    elif a[0, 0] > a[1, 1] and a[0, 0] > a[2, 2]:
        s = math.sqrt(1.0 + a[0, 0] - a[1, 1] - a[2, 2]) * 2
        q = [(a[2, 1] - a[1, 2]) / s, 0.25 * s, (a[0, 1] + a[1, 0]) / s, (a[0, 2] + a[2, 0]) / s]
    elif a[1, 1] > a[2, 2]:
        s = math.sqrt(1.0 + a[1, 1] - a[0, 0] - a[2, 2]) * 2
        q = [(a[0, 2] - a[2, 0]) / s, (a[0, 1] + a[1, 0]) / s, 0.25 * s, (a[1, 2] + a[2, 1]) / s]
    else:
        s = math.sqrt(1.0 + a[2, 2] - a[0, 0] - a[1, 1]) * 2
        q = [(a[1, 0] - a[0, 1]) / s, (a[0, 2] + a[2, 0]) / s, (a[1, 2] + a[2, 1]) / s, 0.25 * s]
    out = quat_normalize(q)
    return out if out[0] >= 0 else -out


_AXIS_TERM = re.compile(r"([+-]?)([XYZxyz])")


class MountError(ValueError):
    """A mount specification is not a proper rotation."""


def parse_signed_axes(spec: str) -> FloatArray:
    """Matrix M (v_body = M @ v_sensor) from a signed-axis string such as ``"-Y-X-Z"``.

    The three terms name, for body x, y and z in turn, the sensor axis that points that way:
    ``"-Y-X-Z"`` means body x = -sensor y, body y = -sensor x, body z = -sensor z (the seed
    board's gyro and magnetometer map). A missing sign means +.
    """
    text = spec.replace(" ", "")
    terms = _AXIS_TERM.findall(text)
    if "".join(s + a for s, a in terms) != text or len(terms) != 3:
        raise MountError(
            f"{spec!r} is not three signed axes; write e.g. \"+X+Y+Z\" or \"-Y-X-Z\""
        )
    axes = [a.upper() for _, a in terms]
    if sorted(axes) != ["X", "Y", "Z"]:
        raise MountError(f"{spec!r} must use each of X, Y and Z exactly once")
    m = np.zeros((3, 3))
    for row, (sign, axis) in enumerate(terms):
        m[row, "XYZ".index(axis.upper())] = -1.0 if sign == "-" else 1.0
    return m


def validate_rotation(m: Matrix, *, tol: float = 1e-6) -> FloatArray:
    """Return ``m`` as an array if it is a proper rotation; raise MountError naming why not."""
    a = np.asarray(m, dtype=float)
    if a.shape != (3, 3):
        raise MountError(f"a mount matrix must be 3x3, got shape {a.shape}")
    if not np.all(np.isfinite(a)):
        raise MountError("a mount matrix must hold finite numbers")
    if not np.allclose(a @ a.T, np.eye(3), atol=tol):
        raise MountError("the mount matrix is not orthonormal (rows must be unit and at 90 deg)")
    det = float(np.linalg.det(a))
    if det < 0:
        raise MountError(
            "the mount is a reflection (determinant -1), which no physical mounting can be: "
            "flip the sign of one axis (an accelerometer's gravity-positive convention is not "
            "part of the mount; imuhal always works in specific force)"
        )
    return a


def parse_mount(spec: str | Sequence[Sequence[float]]) -> FloatArray:
    """A proper rotation matrix from a signed-axis string or a 3x3 matrix."""
    m = parse_signed_axes(spec) if isinstance(spec, str) else np.asarray(spec, dtype=float)
    return validate_rotation(m)
