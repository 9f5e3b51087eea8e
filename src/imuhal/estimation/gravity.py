"""Gravity compensation: the seed's step from an AHRS quaternion to vertical acceleration.

Rotate the body-frame specific force into NED with the body -> NED quaternion and add gravity
back: a_ned = R(q) f_body + g_ned. At rest a_ned = 0; ``-a_ned[2]`` is the upward acceleration
the variometer filter wants. (The seed writes the same in gravity-positive g units as
``a_z_earth - 1``.)
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from imuhal.core.atmosphere import STANDARD_GRAVITY_M_S2
from imuhal.core.frames import FloatArray, Vector, quat_to_matrix


def linear_accel_ned_m_s2(
    q_body_to_ned: Vector,
    specific_force_body_m_s2: Vector,
    gravity_m_s2: float = STANDARD_GRAVITY_M_S2,
) -> FloatArray:
    """Gravity-compensated acceleration in NED (m/s^2) from specific force in body axes."""
    a: FloatArray = quat_to_matrix(q_body_to_ned) @ np.asarray(specific_force_body_m_s2,
                                                               dtype=float)
    a[2] += gravity_m_s2
    return a


def vertical_accel_up_m_s2(
    q_body_to_ned: Sequence[float],
    specific_force_body_m_s2: Sequence[float],
    gravity_m_s2: float = STANDARD_GRAVITY_M_S2,
) -> float:
    """Upward (z up positive) gravity-compensated acceleration in m/s^2."""
    return float(-linear_accel_ned_m_s2(q_body_to_ned, specific_force_body_m_s2, gravity_m_s2)[2])
