"""mahony (ESP32 firmware defaults: Kp 5, Ki 0, gate 0.75-1.25 g) against data set A's truth.

First 7 s (5 s static, 2 s motion ramp), started at the identity. Bounds (degrees), set from
this port's errors with about 50 % margin: 9-DOF, t in [5, 7] s: total RMS 0.24 (bound 0.4),
total max 0.38 (0.6), tilt max 0.25 (0.4); 6-DOF, t >= 1 s: tilt max 0.26 (0.4). The static
tilt error is set by the gyro bias over Kp: |(0.40, -0.25) deg/s| / 5 /s = 0.09 deg.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from imuhal_filters.common.batch import run_batch
from imuhal_filters.common.quat import angle_between_deg, tilt_error_deg
from imuhal_filters.mahony.estimator import MahonyEstimator

DATA = Path(__file__).resolve().parent.parent / "data" / "filters"
G0 = 9.80665


def _data():
    d = np.genfromtxt(DATA / "imu_A_head.csv", delimiter=",", names=True)
    t = np.genfromtxt(DATA / "imu_A_truth_head.csv", delimiter=",", names=True)
    return (d["t_s"], np.c_[d["gx_rads"], d["gy_rads"], d["gz_rads"]],
            -G0 * np.c_[d["ax_g"], d["ay_g"], d["az_g"]],
            np.c_[d["mx_uT"], d["my_uT"], d["mz_uT"]], np.c_[t["qw"], t["qx"], t["qy"], t["qz"]])


def _errors(q: np.ndarray, truth: np.ndarray, rows: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    total = np.array([angle_between_deg(tuple(q[i]), tuple(truth[i])) for i in rows])
    tilt = np.array([tilt_error_deg(tuple(q[i]), tuple(truth[i])) for i in rows])
    return total, tilt


def test_9dof_converges_to_truth_within_stated_bounds() -> None:
    t, gyro, accel, mag, truth = _data()
    q = run_batch(MahonyEstimator(), gyro, accel, mag)
    total, tilt = _errors(q, truth, np.flatnonzero(t >= 5.0))
    assert np.sqrt(np.mean(total**2)) < 0.4
    assert total.max() < 0.6
    assert tilt.max() < 0.4


def test_heading_error_shrinks_while_static() -> None:
    _, gyro, accel, mag, truth = _data()
    q = run_batch(MahonyEstimator(), gyro, accel, mag)
    total, _ = _errors(q, truth, np.array([0, 200, 600, 999]))
    assert total[0] > 19.0  # starts 20 deg off in heading
    assert total[0] > total[1] > total[2] > total[3]
    assert total[3] < 0.5


def test_6dof_tilt_stays_within_bound() -> None:
    t, gyro, accel, _, truth = _data()
    q = run_batch(MahonyEstimator(), gyro, accel, None)
    _, tilt = _errors(q, truth, np.flatnonzero(t >= 1.0))
    assert tilt.max() < 0.4
