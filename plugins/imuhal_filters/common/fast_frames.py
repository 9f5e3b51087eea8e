"""A helper kernel the per-sample steps share (see common/fast.py): the gravity-compensated
acceleration in NED, as ``common.ahrs._linear_accel_ned`` computes it in Python.

It has no signature of its own: numba compiles it into the per-sample kernels that call it.
Their AOT fingerprint and their JIT cache key cover this module (``Kernel.modules``).
"""

from __future__ import annotations

from imuhal_filters.common.fast import jit

_G = 9.80665  # STANDARD_GRAVITY_M_S2


def _linear_accel_ned(w, x, y, z, fx, fy, fz):
    """R(q) f + g for a body -> NED quaternion and specific force ``f`` (m/s^2): the same
    products in the same order as ``common.ahrs._linear_accel_ned``."""
    ww, xx, yy, zz = w * w, x * x, y * y, z * z
    xy, wz, xz, wy, yz, wx = x * y, w * z, x * z, w * y, y * z, w * x
    return ((ww + xx - yy - zz) * fx + 2 * (xy - wz) * fy + 2 * (xz + wy) * fz,
            2 * (xy + wz) * fx + (ww - xx + yy - zz) * fy + 2 * (yz - wx) * fz,
            2 * (xz - wy) * fx + 2 * (yz + wx) * fy + (ww - xx - yy + zz) * fz + _G)


linear_accel_ned = jit(_linear_accel_ned)
