"""The head of conformance data set A (tests/data/filters) in project units, and attitude
error measures against its truth; shared by the AHRS truth tests."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from imuhal_filters.common.quat import angle_between_deg, tilt_error_deg

DATA = Path(__file__).resolve().parent.parent / "data" / "filters"
G0 = 9.80665


def load_head() -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(t_s, gyro rad/s, specific force m/s^2, mag uT, true body->NED quaternions)."""
    d = np.genfromtxt(DATA / "imu_A_head.csv", delimiter=",", names=True)
    t = np.genfromtxt(DATA / "imu_A_truth_head.csv", delimiter=",", names=True)
    return (d["t_s"], np.c_[d["gx_rads"], d["gy_rads"], d["gz_rads"]],
            -G0 * np.c_[d["ax_g"], d["ay_g"], d["az_g"]],   # gravity-positive g -> m/s^2
            np.c_[d["mx_uT"], d["my_uT"], d["mz_uT"]], np.c_[t["qw"], t["qx"], t["qy"], t["qz"]])


def attitude_errors(q: np.ndarray, truth: np.ndarray, rows: np.ndarray
                    ) -> tuple[np.ndarray, np.ndarray]:
    """(total angle, tilt angle) errors in degrees at ``rows``."""
    total = np.array([angle_between_deg(tuple(q[i]), tuple(truth[i])) for i in rows])
    tilt = np.array([tilt_error_deg(tuple(q[i]), tuple(truth[i])) for i in rows])
    return total, tilt
