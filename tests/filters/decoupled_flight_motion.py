"""A seeded synthetic aeroplane flight with known truth, for the decoupled estimator's tests.

The aeroplane flies along its nose at 20 m/s (no angle of attack or sideslip), body NED axes,
100 Hz: level for 3 s, an axial roll (360 deg in 2 s), then straight flight through seeded
turbulence in roll and pitch (1.5 deg RMS, six tones between 0.3 and 2 Hz, as in the
``rc-flight`` scenario) or, with ``turn_deg_s``, a steady turn at that rate through the same
turbulence, coordinated (bank from tan(bank) = V * turn rate / g); ``roll_360`` False
leaves the roll out. The specific force is
V (omega x x_body) - g in body axes; the gyro is the exact incremental rotation with a 3 %
scale error on x (the roll leaves a tilt error of about 11 deg for the accelerometer to
correct) and white noise; the accelerometer has white noise.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from tests.filters.ahrs_cases import G0
from tests.filters.decoupled_motion import _conj, _mul, _rotvec

from imuhal.core.frames import quat_from_euler_deg, quat_to_matrix

RATE_HZ = 100.0
SPEED_M_S = 20.0
ROLL_S = (3.0, 5.0)
GYRO_X_SCALE = 1.03


@dataclass(frozen=True)
class Flight:
    t_s: np.ndarray
    q_true: np.ndarray
    """(N, 4) body -> NED."""
    gyro_rad_s: np.ndarray
    accel_m_s2: np.ndarray

    @property
    def dt_s(self) -> float:
        return 1.0 / RATE_HZ


def _turbulence_deg(t: np.ndarray, rng: np.random.Generator, on_s: float) -> np.ndarray:
    freqs = np.geomspace(0.3, 2.0, 6)
    phases = rng.uniform(0.0, 2 * np.pi, freqs.size)
    amp = 1.5 * np.sqrt(2.0 / freqs.size)  # RMS 1.5 deg
    x = sum(amp * np.sin(2 * np.pi * f * t + p) for f, p in zip(freqs, phases, strict=True))
    ramp = np.clip((t - on_s) / 2.0, 0.0, 1.0)
    return np.asarray(x * ramp)


def flight(seconds: float, turn_deg_s: float = 0.0, *, roll_360: bool = True, seed: int = 3
           ) -> Flight:
    rng = np.random.default_rng(seed)
    n = round(seconds * RATE_HZ)
    t = np.arange(n) / RATE_HZ
    x = np.clip((t - ROLL_S[0]) / (ROLL_S[1] - ROLL_S[0]), 0.0, 1.0)
    roll = 360.0 * (x - np.sin(2 * np.pi * x) / (2 * np.pi))  # starts and ends smoothly
    if not roll_360:
        roll[:] = 0.0
    after = ROLL_S[1] + 1.0
    rate = np.radians(turn_deg_s) * np.clip((t - after) / 2.0, 0.0, 1.0)
    bank = np.degrees(np.arctan(SPEED_M_S * rate / G0))
    yaw = np.degrees(np.cumsum(rate) / RATE_HZ)
    roll = roll + bank + _turbulence_deg(t, rng, after)
    pitch = _turbulence_deg(t, rng, after)
    q = np.array([quat_from_euler_deg(r, p, y) for r, p, y in zip(roll, pitch, yaw, strict=True)])
    omega = np.zeros((n, 3))
    for i in range(n - 1):
        omega[i + 1] = _rotvec(_mul(_conj(q[i]), q[i + 1])) * RATE_HZ
    acc = np.zeros((n, 3))
    for i in range(n):
        _, wq, wr = omega[i]
        kinematic = SPEED_M_S * np.array([0.0, wr, -wq])  # omega x (V, 0, 0)
        acc[i] = kinematic - quat_to_matrix(q[i]).T @ np.array([0.0, 0.0, G0])
    gyro = omega * np.array([GYRO_X_SCALE, 1.0, 1.0]) + rng.normal(0.0, 0.003, (n, 3))
    acc += rng.normal(0.0, 0.05, (n, 3))
    return Flight(t, q, gyro, acc)
