"""madgwick as a pipeline estimator: samples in, estimates out, state, registration."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

import imuhal_filters.madgwick.plugin as madgwick_plugin
from imuhal.core.frames import quat_from_euler_deg, quat_rotate
from imuhal.core.samples import AccelSample, Frame, GyroSample, MagSample, SampleFlag
from imuhal.plugins.manager import load_registry
from imuhal_filters.common.batch import run_batch
from imuhal_filters.madgwick.core import MagReference, mag_gradient
from imuhal_filters.madgwick.estimator import MadgwickEstimator

DATA = Path(__file__).resolve().parent.parent / "data" / "filters"
G0 = 9.80665
B_NED_UT = (25.0, 0.0, 43.30127)


def _inputs() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    d = np.genfromtxt(DATA / "imu_A_head.csv", delimiter=",", names=True)
    return (np.c_[d["gx_rads"], d["gy_rads"], d["gz_rads"]],
            -G0 * np.c_[d["ax_g"], d["ay_g"], d["az_g"]],
            np.c_[d["mx_uT"], d["my_uT"], d["mz_uT"]])


def _samples(gyro, accel, mag, t0_ns: int = 0, period_ns: int = 5_000_000):
    for i in range(len(gyro)):
        t = t0_ns + i * period_ns
        yield AccelSample(t_ns=t, device="imu", frame=Frame.BODY_NED, accel_m_s2=tuple(accel[i]))
        yield MagSample(t_ns=t, device="mag", frame=Frame.BODY_NED, mag_ut=tuple(mag[i]))
        yield GyroSample(t_ns=t, device="imu", frame=Frame.BODY_NED, gyro_rad_s=tuple(gyro[i]))


def _run(est, samples) -> list:
    out = []
    for s in samples:
        out.extend(est.process(s))
    return out


def test_registered_under_its_name() -> None:
    reg = load_registry(entry_point_plugins=False, extra=[("madgwick", madgwick_plugin)])
    assert reg.estimators.get("madgwick") is MadgwickEstimator


def test_one_estimate_per_gyro_sample_with_source_and_timestamp() -> None:
    gyro, accel, mag = _inputs()
    est = MadgwickEstimator(instance="ahrs1")
    out = _run(est, _samples(gyro[:20], accel[:20], mag[:20], t0_ns=7))
    assert [e.t_ns for e in out] == [7 + i * 5_000_000 for i in range(20)]
    assert {e.source for e in out} == {"ahrs1"}


def test_samples_path_equals_batch_path() -> None:
    gyro, accel, mag = _inputs()
    out = _run(MadgwickEstimator(), _samples(gyro[:300], accel[:300], mag[:300]))
    q = run_batch(MadgwickEstimator(), gyro[:300], accel[:300], mag[:300])
    assert np.abs(np.array([e.q_body_to_ned for e in out]) - q).max() < 1e-15


def test_invalid_samples_are_skipped_and_counted() -> None:
    gyro, accel, mag = _inputs()
    clean = _run(MadgwickEstimator(), _samples(gyro[:100], accel[:100], mag[:100]))
    est = MadgwickEstimator()
    out = []
    for s in _samples(gyro[:100], accel[:100], mag[:100]):
        out.extend(est.process(s))
        if isinstance(s, GyroSample):
            # garbage that must be ignored: flagged copies with absurd values
            bad_a = AccelSample(t_ns=s.t_ns, device="imu", frame=Frame.BODY_NED,
                                accel_m_s2=(1e3, 0.0, 0.0), flags=SampleFlag.SATURATED)
            bad_m = MagSample(t_ns=s.t_ns, device="mag", frame=Frame.BODY_NED,
                              mag_ut=(-4096.0, 0.0, 0.0), flags=SampleFlag.OVERFLOW)
            bad_g = GyroSample(t_ns=s.t_ns + 1, device="imu", frame=Frame.BODY_NED,
                               gyro_rad_s=(9.0, 9.0, 9.0), flags=SampleFlag.BUS_ERROR)
            assert est.process(bad_a) == est.process(bad_m) == est.process(bad_g) == []
    assert [e.q_body_to_ned for e in out] == [e.q_body_to_ned for e in clean]
    assert est.diagnostics()["invalid"] == {"gyro": 100, "accel": 100, "mag": 100}


def test_sensor_frame_samples_are_refused() -> None:
    with pytest.raises(ValueError, match="body NED"):
        MadgwickEstimator().process(GyroSample(t_ns=0, device="imu", gyro_rad_s=(0, 0, 0)))


def test_state_round_trips_through_json_and_continues_identically() -> None:
    gyro, accel, mag = _inputs()
    samples = list(_samples(gyro[:600], accel[:600], mag[:600]))
    whole = _run(MadgwickEstimator(), samples)
    first = MadgwickEstimator()
    _run(first, samples[:900])  # 300 IMU steps
    second = MadgwickEstimator()
    second.set_state(json.loads(json.dumps(first.get_state())))
    rest = _run(second, samples[900:])
    assert [e.q_body_to_ned for e in rest] == [e.q_body_to_ned for e in whole[300:]]
    assert second.diagnostics()["steps"] == 600


def test_step_length_comes_from_gyro_timestamps() -> None:
    """A constant 90 deg/s yaw rate sampled irregularly still integrates to the right angle."""
    rng = np.random.default_rng(5)
    times = np.cumsum(rng.uniform(2e6, 8e6, 400)).astype(int)  # 2-8 ms jitter
    est = MadgwickEstimator({"beta": 0.0, "initial_attitude": "identity"})
    rate = math.radians(90.0)
    for t in times:
        est.process(GyroSample(t_ns=int(t), device="imu", frame=Frame.BODY_NED,
                               gyro_rad_s=(0.0, 0.0, rate)))
    # each first-order step q + 0.5 q (0, w) dt, normalised, turns by 2 atan(w dt / 2)
    dts = np.r_[est.settings.sample_period_s, np.diff(times) * 1e-9]
    expected = math.degrees(np.sum(2 * np.arctan(rate * dts / 2)))
    yaw = math.degrees(2 * math.atan2(est.quaternion[3], est.quaternion[0]))
    assert yaw == pytest.approx(expected, abs=1e-9)


def test_linear_acceleration_is_gravity_compensated_in_ned() -> None:
    """At the true attitude and at rest, the NED linear acceleration is ~0 (< 1e-9 m/s^2)."""
    q = quat_from_euler_deg(-3.0, 5.0, 20.0)
    f_body = quat_rotate(np.array([q[0], -q[1], -q[2], -q[3]]), (0.0, 0.0, -G0))
    m_body = quat_rotate(np.array([q[0], -q[1], -q[2], -q[3]]), B_NED_UT)
    est = MadgwickEstimator({"beta": 0.0})  # hold the attitude: a gradient step always moves
    est.set_state({**est.get_state(), "q": list(q)})
    est.process(AccelSample(t_ns=0, device="imu", frame=Frame.BODY_NED, accel_m_s2=tuple(f_body)))
    est.process(MagSample(t_ns=0, device="mag", frame=Frame.BODY_NED, mag_ut=tuple(m_body)))
    (e,) = est.process(GyroSample(t_ns=0, device="imu", frame=Frame.BODY_NED,
                                  gyro_rad_s=(0.0, 0.0, 0.0)))
    assert np.abs(np.asarray(e.linear_accel_ned_m_s2)).max() < 1e-9


def _unit_field_in_body(q) -> tuple[float, float, float]:
    m = quat_rotate(np.array([q[0], -q[1], -q[2], -q[3]]), B_NED_UT)
    return tuple(m / np.linalg.norm(m))


@pytest.mark.parametrize("euler_deg", [(0.0, 0.0, 0.0), (-3.0, 5.0, 20.0), (40.0, -30.0, 170.0)])
def test_paper_form_has_no_magnetometer_gradient_at_the_true_attitude(euler_deg) -> None:
    q = tuple(quat_from_euler_deg(*euler_deg))
    assert np.abs(mag_gradient(q, _unit_field_in_body(q), MagReference.PAPER)).max() < 1e-12


def test_release_form_pulls_a_tilted_board_off_the_true_attitude() -> None:
    """The halved reference of the x-io release: non-zero gradient at the truth when tilted."""
    q = tuple(quat_from_euler_deg(-3.0, 5.0, 20.0))
    g = np.linalg.norm(mag_gradient(q, _unit_field_in_body(q), MagReference.XIO_RELEASE))
    assert g > 0.01


@pytest.mark.parametrize("heading_error_deg", [2.0, 10.0])
def test_release_form_halves_the_heading_gradient_of_a_level_board(heading_error_deg) -> None:
    m = _unit_field_in_body((1.0, 0.0, 0.0, 0.0))
    q = tuple(quat_from_euler_deg(0.0, 0.0, heading_error_deg))
    paper = np.linalg.norm(mag_gradient(q, m, MagReference.PAPER))
    release = np.linalg.norm(mag_gradient(q, m, MagReference.XIO_RELEASE))
    assert release / paper == pytest.approx(0.5, abs=0.01)


def test_preset_handheld_is_beta_0_1_without_the_soft_gate() -> None:
    s = MadgwickEstimator({"preset": "handheld"}).settings
    assert (s.beta, s.accel_soft_gate_g) == (0.1, None)
    assert MadgwickEstimator().settings.accel_soft_gate_g is not None
