"""Synthetic sample streams shared by the cross-AHRS behaviour tests (alignment, limits, turns)."""

from __future__ import annotations

from collections.abc import Iterator

import numpy as np

from imuhal.core.frames import quat_from_euler_deg, quat_to_matrix
from imuhal.core.samples import AccelSample, Frame, GyroSample, MagSample, Sample
from imuhal.estimation.base import Estimator
from imuhal.estimation.outputs import AttitudeEstimate
from imuhal_filters.decoupled.estimator import DecoupledEstimator
from imuhal_filters.freescale.estimator import Freescale6DofEstimator, Freescale9DofEstimator
from imuhal_filters.imufilter.estimator import ImuFilterEstimator
from imuhal_filters.madgwick.estimator import MadgwickEstimator
from imuhal_filters.mahony.estimator import MahonyEstimator

G0 = 9.80665
FIELD_NED_UT = np.array([20.0, 0.0, 44.0])
"""A mid-latitude field: 48 uT, 65.6 deg dip."""
PERIOD_NS = 5_000_000

AHRS = {
    "madgwick": MadgwickEstimator,
    "mahony": MahonyEstimator,
    "imufilter": ImuFilterEstimator,
    "freescale-9dof": Freescale9DofEstimator,
    "freescale-6dof": Freescale6DofEstimator,
    "decoupled": DecoupledEstimator,
}
SIX_DOF = {"imufilter", "freescale-6dof"}


def make(name: str, settings: dict | None = None) -> Estimator:
    base: dict = {"field_strength_ut": float(np.linalg.norm(FIELD_NED_UT))} if (
        name == "freescale-9dof") else {}
    return AHRS[name]({**base, **(settings or {})})


def at_rest(q: np.ndarray, seconds: float, seed: int = 3, noise: bool = True
            ) -> Iterator[Sample]:
    """A board held still at attitude ``q`` (body -> NED): 200 Hz accel, mag and gyro with
    small white noise (accel 0.02 m/s^2, gyro 0.002 rad/s, mag 0.2 uT)."""
    rng = np.random.default_rng(seed)
    r = quat_to_matrix(q)
    f = r.T @ np.array([0.0, 0.0, -G0])
    m = r.T @ FIELD_NED_UT
    k = 1.0 if noise else 0.0
    for i in range(round(seconds * 200)):
        t = i * PERIOD_NS
        yield AccelSample(t_ns=t, device="imu", frame=Frame.BODY_NED,
                          accel_m_s2=tuple(f + k * rng.normal(0, 0.02, 3)))
        yield MagSample(t_ns=t, device="mag", frame=Frame.BODY_NED,
                        mag_ut=tuple(m + k * rng.normal(0, 0.2, 3)))
        yield GyroSample(t_ns=t, device="imu", frame=Frame.BODY_NED,
                         gyro_rad_s=tuple(k * rng.normal(0, 0.002, 3)))


def run(est: Estimator, samples: Iterator[Sample]) -> list[AttitudeEstimate]:
    out: list[AttitudeEstimate] = []
    for s in samples:
        out += [e for e in est.process(s) if isinstance(e, AttitudeEstimate)]
    return out


def error_deg(name: str, e: AttitudeEstimate, q_true: np.ndarray) -> float:
    """Total attitude error, or tilt error for a 6-DOF filter (its heading is arbitrary)."""
    q = np.asarray(e.q_body_to_ned)
    if name in SIX_DOF:
        d_est = quat_to_matrix(q)[2]
        d_true = quat_to_matrix(q_true)[2]
        return float(np.degrees(np.arccos(np.clip(d_est @ d_true, -1.0, 1.0))))
    return float(np.degrees(2 * np.arccos(min(1.0, abs(float(q @ q_true))))))


def attitude(roll: float, pitch: float, yaw: float) -> np.ndarray:
    return quat_from_euler_deg(roll, pitch, yaw)
