"""The edge between imuhal's NED body frame and VQF's conventions.

VQF (Laidig and Seel 2023) works in the sensor's own axes, takes the accelerometer as
specific force (a sensor at rest with z up reads +9.81 m/s^2 along z) and returns
quaternions rotating the sensor frame into an ENU earth frame (its 9-DOF heading: x east).
imuhal's estimators see body forward-right-down (NED body) samples, so the plugin hands VQF
the same vectors in forward-left-up axes (imuhal's ``enu`` convention, core/conventions) and
brings its quaternions back to body -> NED. Both steps are exact signed permutations; the
per-step forms precompute them once (they run at the gyro rate).
"""

from __future__ import annotations

import numpy as np

from imuhal.core.conventions import ENU, NED, VectorKind, convert_quat, vector_from_ned
from imuhal.core.frames import FloatArray

_TO_FLU = vector_from_ned(np.eye(3), ENU, VectorKind.ANGULAR_RATE).T
"""Columns: the FLU coordinates of the FRD unit vectors (a signed permutation)."""
_ACCEL_SIGN = ENU.accel_sign.factor * NED.accel_sign.factor
_E, _X, _Y, _Z = (convert_quat(np.eye(4)[i], ENU, NED) for i in range(4))
"""The images of the basis quaternions 1, i, j, k: convert_quat is linear in q."""


def to_vqf(v_ned: FloatArray, kind: VectorKind) -> FloatArray:
    """Body NED vector(s) (specific force for the accelerometer) -> VQF's FLU input."""
    return np.ascontiguousarray(vector_from_ned(v_ned, ENU, kind), dtype=float)


def from_vqf(q_flu_to_enu: FloatArray) -> FloatArray:
    """VQF quaternion(s) (FLU sensor -> ENU) -> body FRD -> NED."""
    return convert_quat(q_flu_to_enu, ENU, NED)


def vector_to_vqf(v: tuple[float, float, float], kind: VectorKind) -> FloatArray:
    """One body NED vector -> VQF's FLU input (the per-step form of ``to_vqf``)."""
    out = _TO_FLU @ np.array(v, dtype=float)
    return out * _ACCEL_SIGN if kind is VectorKind.SPECIFIC_FORCE else out


def quat_from_vqf(q: FloatArray) -> tuple[float, float, float, float]:
    """One VQF quaternion -> body FRD -> NED (the per-step form of ``from_vqf``)."""
    w, x, y, z = (float(c) for c in q)
    r = w * _E + x * _X + y * _Y + z * _Z
    return (float(r[0]), float(r[1]), float(r[2]), float(r[3]))


def quat_to_vqf(q: tuple[float, float, float, float]) -> FloatArray:
    """One body FRD -> NED quaternion -> VQF's (FLU sensor -> ENU): ``quat_from_vqf``'s
    inverse."""
    return convert_quat(np.array(q, dtype=float), NED, ENU)
