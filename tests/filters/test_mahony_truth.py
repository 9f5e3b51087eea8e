"""mahony, ``preset: seed`` (ESP32 firmware: Kp 5, Ki 0, gate 0.75-1.25 g), vs data set A's truth.

First 7 s (5 s static, 2 s motion ramp), started at the identity. Bounds (degrees), set from
this port's errors with about 50 % margin: 9-DOF, t in [5, 7] s: total RMS 0.24 (bound 0.4),
total max 0.38 (0.6), tilt max 0.25 (0.4); 6-DOF, t >= 1 s: tilt max 0.26 (0.4). The static
tilt error is set by the gyro bias over Kp: |(0.40, -0.25) deg/s| / 5 /s = 0.09 deg.
"""

from __future__ import annotations

import numpy as np
from tests.filters.dataset_a import attitude_errors, load_head

from imuhal_filters.common.batch import run_batch
from imuhal_filters.mahony.estimator import MahonyEstimator


def test_9dof_converges_to_truth_within_stated_bounds() -> None:
    t, gyro, accel, mag, truth = load_head()
    q = run_batch(MahonyEstimator({"preset": "seed"}), gyro, accel, mag)
    total, tilt = attitude_errors(q, truth, np.flatnonzero(t >= 5.0))
    assert np.sqrt(np.mean(total**2)) < 0.4
    assert total.max() < 0.6
    assert tilt.max() < 0.4


def test_heading_error_shrinks_while_static() -> None:
    _, gyro, accel, mag, truth = load_head()
    q = run_batch(MahonyEstimator({"preset": "seed"}), gyro, accel, mag)
    total, _ = attitude_errors(q, truth, np.array([0, 200, 600, 999]))
    assert total[0] > 19.0  # starts 20 deg off in heading
    assert total[0] > total[1] > total[2] > total[3]
    assert total[3] < 0.5


def test_6dof_tilt_stays_within_bound() -> None:
    t, gyro, accel, _, truth = load_head()
    q = run_batch(MahonyEstimator({"preset": "seed"}), gyro, accel, None)
    _, tilt = attitude_errors(q, truth, np.flatnonzero(t >= 1.0))
    assert tilt.max() < 0.4
