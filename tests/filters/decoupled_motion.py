"""A seeded synthetic hand-held recording with known truth, for the decoupled estimator's tests.

The board turns (roll, pitch and yaw sinusoids) and is shaken back and forth from 2 s on (a
horizontal translation of 0.3 m at 0.7 Hz), body NED axes, 100 Hz. The gyro is the exact incremental
rotation between consecutive truth samples plus a constant bias and white noise, so the only
errors an estimator meets are the bias, the noise and the linear acceleration.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from tests.filters.ahrs_cases import FIELD_NED_UT, G0

from imuhal.core.frames import quat_from_euler_deg, quat_to_matrix

RATE_HZ = 100.0


@dataclass(frozen=True)
class Motion:
    q_true: np.ndarray
    """(N, 4) body -> NED."""
    gyro_rad_s: np.ndarray
    accel_m_s2: np.ndarray
    mag_ut: np.ndarray

    @property
    def dt_s(self) -> float:
        return 1.0 / RATE_HZ


def _rotvec(q: np.ndarray) -> np.ndarray:
    w, v = q[0], q[1:]
    n = float(np.linalg.norm(v))
    if n < 1e-15:
        return 2.0 * v
    return 2.0 * np.arctan2(n, w) * v / n


def _conj(q: np.ndarray) -> np.ndarray:
    return np.array([q[0], -q[1], -q[2], -q[3]])


def _mul(p: np.ndarray, q: np.ndarray) -> np.ndarray:
    w1, x1, y1, z1 = p
    w2, x2, y2, z2 = q
    return np.array([w1 * w2 - x1 * x2 - y1 * y2 - z1 * z2, w1 * x2 + x1 * w2 + y1 * z2 - z1 * y2,
                     w1 * y2 - x1 * z2 + y1 * w2 + z1 * x2, w1 * z2 + x1 * y2 - y1 * x2 + z1 * w2])


def hand_motion(seconds: float, bias_rad_s: tuple[float, float, float], seed: int = 5,
                shake_m: float = 0.3) -> Motion:
    rng = np.random.default_rng(seed)
    n = round(seconds * RATE_HZ)
    t = np.arange(n) / RATE_HZ
    roll = 30.0 * np.sin(2 * np.pi * 0.13 * t)
    pitch = 20.0 * np.sin(2 * np.pi * 0.21 * t + 1.0)
    yaw = 60.0 * np.sin(2 * np.pi * 0.05 * t)
    q = np.array([quat_from_euler_deg(r, p, y) for r, p, y in zip(roll, pitch, yaw, strict=True)])
    w = 2 * np.pi * 0.7
    a_ned = np.zeros((n, 3))
    # the shaking starts after 2 s, so the aligned start sees gravity alone
    on = t >= 2.0
    a_ned[on, 0] = -shake_m * w * w * np.sin(w * (t[on] - 2.0))
    a_ned[on, 1] = -0.5 * shake_m * w * w * np.sin(w * (t[on] - 2.0))
    gyro = np.zeros((n, 3))
    acc = np.zeros((n, 3))
    mag = np.zeros((n, 3))
    for i in range(n):
        if i + 1 < n:
            gyro[i + 1] = _rotvec(_mul(_conj(q[i]), q[i + 1])) * RATE_HZ
        r = quat_to_matrix(q[i])
        acc[i] = r.T @ (a_ned[i] - np.array([0.0, 0.0, G0]))
        mag[i] = r.T @ FIELD_NED_UT
    gyro += np.asarray(bias_rad_s) + rng.normal(0.0, 0.003, (n, 3))
    acc += rng.normal(0.0, 0.05, (n, 3))
    mag += rng.normal(0.0, 0.3, (n, 3))
    return Motion(q, gyro, acc, mag)


def tilt_error_deg(q: np.ndarray, q_true: np.ndarray) -> np.ndarray:
    """(N,) angle between the estimated and the true down axes."""
    d_est = np.array([quat_to_matrix(x)[2] for x in q])
    d_true = np.array([quat_to_matrix(x)[2] for x in q_true])
    return np.degrees(np.arccos(np.clip(np.sum(d_est * d_true, axis=1), -1.0, 1.0)))
