"""Run a Freescale Kalman filter over whole arrays of fast samples (the tests' entry point).

Inputs are in the reference's units and in the sensor axes and accelerometer sign of the
chosen coordinate system (for NED: body forward-right-down, accelerometer gravity positive,
g; gyro deg/s; magnetometer calibrated uT). Row ``i`` is fast sample ``i``; a Kalman step
runs after every ``oversample_ratio`` rows, on the gyro rows of that window and on the last
accelerometer/magnetometer row of it (or the window mean, per ``accel_mag_input``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from imuhal.core.frames import FloatArray
from imuhal_filters.freescale.coords import quat_body_to_ned
from imuhal_filters.freescale.kalman import FreescaleKalman
from imuhal_filters.freescale.settings import (
    Freescale6DofSettings,
    Freescale9DofSettings,
    FreescaleCommonSettings,
)


@dataclass(frozen=True)
class BatchResult:
    """One row per Kalman step. Quaternions are scalar first."""

    row: np.ndarray
    """Index of the fast sample that completed each Kalman window."""
    valid: np.ndarray
    """False for the initialising step."""
    q_sensor_to_global: FloatArray
    """(n, 4) the filter's own quaternion (for NED: body -> NED)."""
    q_body_to_ned: FloatArray
    """(n, 4) body -> NED whatever the coordinate system."""
    euler_deg: FloatArray
    """(n, 3) the system's own roll phi, pitch theta, yaw psi (0..360)."""
    gyro_offset_dps: FloatArray
    """(n, 3) gyro offset estimate (deg/s, sensor axes)."""
    inclination_deg: FloatArray
    mag_jamming: np.ndarray


def run_9dof(accel_g: FloatArray, gyro_dps: FloatArray, mag_ut: FloatArray,
             settings: Freescale9DofSettings | None = None) -> BatchResult:
    """fRun_9DOF_GBY_KALMAN over arrays of shape (n, 3)."""
    return _run(settings or Freescale9DofSettings(), accel_g, gyro_dps, mag_ut, use_mag=True)


def run_6dof(accel_g: FloatArray, gyro_dps: FloatArray,
             settings: Freescale6DofSettings | None = None) -> BatchResult:
    """fRun_6DOF_GY_KALMAN over arrays of shape (n, 3)."""
    return _run(settings or Freescale6DofSettings(), accel_g, gyro_dps, None, use_mag=False)


def _run(settings: FreescaleCommonSettings, accel_g: FloatArray, gyro_dps: FloatArray,
         mag_ut: FloatArray | None, *, use_mag: bool) -> BatchResult:
    accel = np.asarray(accel_g, dtype=float)
    gyro = np.asarray(gyro_dps, dtype=float)
    mag = None if mag_ut is None else np.asarray(mag_ut, dtype=float)
    if accel.shape != gyro.shape or (mag is not None and mag.shape != accel.shape):
        raise ValueError("accel, gyro and mag arrays must have the same (n, 3) shape")
    kf = FreescaleKalman(settings, use_mag=use_mag)
    ratio = settings.oversample_ratio
    average = settings.accel_mag_input == "average"
    rows, steps = [], []
    for end in range(ratio - 1, len(accel), ratio):
        window = slice(end - ratio + 1, end + 1)
        a = accel[window].mean(axis=0) if average else accel[end]
        m = None
        if mag is not None:
            m = mag[window].mean(axis=0) if average else mag[end]
        steps.append(kf.step(a, gyro[window], m))
        rows.append(end)
    cs = settings.coordinate_system
    return BatchResult(
        row=np.array(rows, dtype=int),
        valid=np.array([st.valid for st in steps], dtype=bool),
        q_sensor_to_global=np.array([st.q_sensor_to_global for st in steps]).reshape(-1, 4),
        q_body_to_ned=np.array([quat_body_to_ned(cs, st.q_sensor_to_global)
                                for st in steps]).reshape(-1, 4),
        euler_deg=np.array([[st.euler_deg[k] for k in ("phi", "theta", "psi")]
                            for st in steps]).reshape(-1, 3),
        gyro_offset_dps=np.array([st.gyro_offset_dps for st in steps]).reshape(-1, 3),
        inclination_deg=np.array([st.inclination_deg for st in steps]),
        mag_jamming=np.array([st.mag_jamming for st in steps], dtype=bool),
    )
