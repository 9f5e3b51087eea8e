"""mahony: the firmware's 0.75-1.25 g gate, the integral term, state, samples, registration."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

import imuhal_filters.mahony.plugin as mahony_plugin
from imuhal.core.frames import quat_from_euler_deg
from imuhal.core.samples import AccelSample, Frame, GyroSample, MagSample, SampleFlag
from imuhal.plugins.manager import load_registry
from imuhal_filters.mahony.estimator import MahonyEstimator

G0 = 9.80665
LEVEL_MAG_UT = (25.0, 0.0, 43.3)
BIAS_RAD_S = tuple(math.radians(b) for b in (0.4, -0.25, 0.15))


def _feed(est: MahonyEstimator, n: int, accel_g: float = 1.0, gyro=(0.0, 0.0, 0.0),
          mag: bool = True, t0: int = 0, bad_every: int = 0) -> list:
    """A level, north-facing board at rest whose accelerometer reads ``accel_g`` g."""
    out = []
    for i in range(n):
        t = t0 + i * 5_000_000
        est.process(AccelSample(t_ns=t, device="imu", frame=Frame.BODY_NED,
                                accel_m_s2=(0.0, 0.0, -accel_g * G0)))
        if mag:
            est.process(MagSample(t_ns=t, device="mag", frame=Frame.BODY_NED,
                                  mag_ut=LEVEL_MAG_UT))
        if bad_every and i % bad_every == 0:
            est.process(GyroSample(t_ns=t, device="imu", frame=Frame.BODY_NED,
                                   gyro_rad_s=(5.0, 5.0, 5.0), flags=SampleFlag.NAN))
        out.extend(est.process(GyroSample(t_ns=t, device="imu", frame=Frame.BODY_NED,
                                          gyro_rad_s=gyro)))
    return out


def _tilt(est: MahonyEstimator) -> np.ndarray:
    q = quat_from_euler_deg(10.0, -5.0, 30.0)
    est.set_state({**est.get_state(), "q": list(q)})
    return q


def test_registered_under_its_name() -> None:
    reg = load_registry(entry_point_plugins=False, extra=[("mahony", mahony_plugin)])
    assert reg.estimators.get("mahony") is MahonyEstimator


def test_seed_preset_is_the_esp32_firmware_settings() -> None:
    s = MahonyEstimator({"preset": "seed"}).settings
    assert (s.kp, s.ki, s.accel_gate_g) == (5.0, 0.0, (0.75, 1.25))
    assert s.initial_attitude == "identity"


def test_a_preset_only_fills_what_the_settings_leave_out() -> None:
    s = MahonyEstimator({"preset": "seed", "kp": 2.0}).settings
    assert (s.kp, s.accel_gate_g) == (2.0, (0.75, 1.25))


def test_an_unknown_preset_names_the_known_ones() -> None:
    with pytest.raises(ValueError, match="presets: default, reference, seed"):
        MahonyEstimator({"preset": "fast"})


@pytest.mark.parametrize("accel_g", [0.5, 0.74, 1.26, 3.0])
def test_outside_the_gate_no_feedback_at_all(accel_g: float) -> None:
    est = MahonyEstimator({"preset": "seed"})
    q0 = _tilt(est)
    out = _feed(est, 100, accel_g)
    assert not any(e.diagnostics["gate_open"] for e in out)
    assert np.abs(np.asarray(out[-1].q_body_to_ned) - q0).max() < 1e-12  # gyro reads zero
    assert est.diagnostics()["gate_closed_steps"] == 100


@pytest.mark.parametrize("accel_g", [0.76, 1.0, 1.24])
def test_inside_the_gate_converges_to_level_and_north(accel_g: float) -> None:
    est = MahonyEstimator({"preset": "seed"})
    _tilt(est)
    # tilt settles with 1/Kp = 0.2 s; heading slower (the horizontal field is half of |B|)
    out = _feed(est, 2000, accel_g)
    assert all(e.diagnostics["gate_open"] for e in out)
    roll, pitch, yaw = out[-1].roll_pitch_yaw_deg
    assert max(abs(roll), abs(pitch), abs(yaw)) < 0.05


def test_integral_gain_learns_the_gyro_bias() -> None:
    """Ki > 0 on a static board with a biased gyro: the integral converges to the bias
    (within 2 %) and the attitude error caused by the bias vanishes (< 0.01 deg). Heading
    is the slow axis (only the horizontal field, half of |B|, observes it): 80 s."""
    est = MahonyEstimator({"preset": "seed", "kp": 1.0, "ki": 0.2})
    out = _feed(est, 16000, gyro=BIAS_RAD_S)
    assert np.allclose(est.gyro_bias_rad_s, BIAS_RAD_S, rtol=0.02)
    assert max(abs(a) for a in out[-1].roll_pitch_yaw_deg) < 0.01


def test_without_integral_the_bias_leaves_an_error_of_bias_over_kp() -> None:
    est = MahonyEstimator({"preset": "seed", "kp": 1.0})
    out = _feed(est, 4000, gyro=BIAS_RAD_S, mag=False)  # 6-DOF: no heading coupling
    assert est.gyro_bias_rad_s == (0.0, 0.0, 0.0)
    roll, pitch, _ = out[-1].roll_pitch_yaw_deg
    assert 0.3 < max(abs(roll), abs(pitch)) < 0.5  # bias_x / Kp = 0.4 deg/s / 1 /s


def test_invalid_samples_are_skipped_and_counted() -> None:
    clean = _feed(MahonyEstimator({"preset": "seed"}), 50)
    est = MahonyEstimator({"preset": "seed"})
    noisy = _feed(est, 50, bad_every=5)
    assert [e.q_body_to_ned for e in noisy] == [e.q_body_to_ned for e in clean]
    assert est.diagnostics()["invalid"]["gyro"] == 10


def test_state_round_trip_continues_identically() -> None:
    ref = MahonyEstimator({"preset": "seed", "ki": 0.3})
    _tilt(ref)
    whole = _feed(ref, 400, gyro=BIAS_RAD_S)
    a = MahonyEstimator({"preset": "seed", "ki": 0.3})
    _tilt(a)
    _feed(a, 150, gyro=BIAS_RAD_S)
    b = MahonyEstimator({"preset": "seed", "ki": 0.3})
    b.set_state(json.loads(json.dumps(a.get_state())))
    rest = _feed(b, 250, gyro=BIAS_RAD_S, t0=150 * 5_000_000)
    assert [e.q_body_to_ned for e in rest] == [e.q_body_to_ned for e in whole[150:]]
