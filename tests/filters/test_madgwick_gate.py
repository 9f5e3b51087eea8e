"""madgwick: the seed's accelerometer gate (correction only while 0.6 g < |a| < 1.4 g)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from imuhal.core.frames import quat_from_euler_deg
from imuhal.core.samples import AccelSample, Frame, GyroSample, MagSample
from imuhal_filters.madgwick.estimator import MadgwickEstimator

G0 = 9.80665
LEVEL_MAG_UT = (25.0, 0.0, 43.3)  # earth field of data set A seen by a level, north-facing board


def _tilted(est: MadgwickEstimator) -> np.ndarray:
    """Put the filter 10 deg off in roll and 30 deg off in yaw; return that quaternion."""
    q = quat_from_euler_deg(10.0, 0.0, 30.0)
    est.set_state({**est.get_state(), "q": list(q)})
    return q


def _step(est: MadgwickEstimator, t_ns: int, accel_g_level: float, with_mag: bool = True):
    """A level board at rest whose accelerometer reads ``accel_g_level`` g of specific force."""
    est.process(AccelSample(t_ns=t_ns, device="imu", frame=Frame.BODY_NED,
                            accel_m_s2=(0.0, 0.0, -accel_g_level * G0)))
    if with_mag:
        est.process(MagSample(t_ns=t_ns, device="mag", frame=Frame.BODY_NED, mag_ut=LEVEL_MAG_UT))
    return est.process(GyroSample(t_ns=t_ns, device="imu", frame=Frame.BODY_NED,
                                  gyro_rad_s=(0.0, 0.0, 0.0)))[0]


@pytest.mark.parametrize("magnitude_g", [0.3, 0.59, 1.41, 2.5])
def test_closed_gate_skips_the_whole_gradient_step_including_mag(magnitude_g: float) -> None:
    est = MadgwickEstimator({"preset": "seed"})
    q0 = _tilted(est)
    for i in range(50):
        e = _step(est, i * 5_000_000, magnitude_g)
        assert e.diagnostics["gate_open"] is False
        assert e.diagnostics["mag_used"] is False
    # gyro reads zero, so the attitude must not have moved at all (1e-12: float rounding)
    assert np.abs(np.asarray(e.q_body_to_ned) - q0).max() < 1e-12
    assert est.diagnostics()["gate_closed_steps"] == 50


@pytest.mark.parametrize("magnitude_g", [0.61, 1.0, 1.39])
def test_open_gate_corrects_towards_the_accelerometer(magnitude_g: float) -> None:
    est = MadgwickEstimator({"preset": "seed", "beta": 0.5})
    _tilted(est)
    for i in range(400):  # 2 s at beta 0.5 rad/s: enough to remove a 10 deg tilt
        e = _step(est, i * 5_000_000, magnitude_g, with_mag=False)
        assert e.diagnostics["gate_open"] is True
    roll, pitch, _ = e.roll_pitch_yaw_deg
    # a fixed-length gradient step chatters about the minimum by ~2 beta dt = 0.29 deg
    assert abs(roll) < 0.5 and abs(pitch) < 0.5


def test_gate_bounds_are_settings_and_none_disables_it() -> None:
    narrow = MadgwickEstimator({"preset": "seed", "accel_gate_g": (0.9, 1.1)})
    assert _step(narrow, 0, 1.15).diagnostics["gate_open"] is False
    off = MadgwickEstimator({"preset": "seed", "accel_gate_g": None, "beta": 0.5})
    _tilted(off)
    for i in range(400):
        e = _step(off, i * 5_000_000, 2.5, with_mag=False)
    assert e.diagnostics["gate_open"] is True
    assert abs(e.roll_pitch_yaw_deg[0]) < 0.5  # 2 beta dt chatter, see above


def test_gate_opening_again_resumes_correction() -> None:
    est = MadgwickEstimator({"preset": "seed", "beta": 0.5})
    _tilted(est)
    for i in range(100):
        _step(est, i * 5_000_000, 2.0, with_mag=False)
    assert math.isclose(est.quaternion @ quat_from_euler_deg(10.0, 0.0, 30.0), 1.0, abs_tol=1e-12)
    for i in range(100, 500):
        e = _step(est, i * 5_000_000, 1.0, with_mag=False)
    assert abs(e.roll_pitch_yaw_deg[0]) < 0.5  # 2 beta dt chatter, see above
