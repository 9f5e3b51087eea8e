"""imufilter: setup, the accelerometer band, heading rotation, frame helpers, velocity, state."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

import imuhal_filters.imufilter.plugin as imufilter_plugin
from imuhal.core.frames import euler_deg_from_quat, quat_from_euler_deg, quat_to_matrix
from imuhal.core.samples import AccelSample, Frame, GyroSample, SampleFlag
from imuhal.plugins.manager import load_registry
from imuhal_filters.common.quat import to_global
from imuhal_filters.imufilter.core import setup_quaternion
from imuhal_filters.imufilter.estimator import ImuFilterEstimator
from imuhal_filters.imufilter.velocity import VelocityState, velocity_step

G0 = 9.80665
REST = (0.0, 0.0, -G0)


def _rest_f(q) -> tuple[float, float, float]:
    """Specific force a board at attitude q reads at rest."""
    r = quat_to_matrix(q)
    return tuple(r.T @ np.array(REST))


def test_registered_under_its_name() -> None:
    reg = load_registry(entry_point_plugins=False, extra=[("imufilter", imufilter_plugin)])
    assert reg.estimators.get("imufilter") is ImuFilterEstimator


def test_no_estimate_until_the_first_valid_accel_sample() -> None:
    est = ImuFilterEstimator()
    g = GyroSample(t_ns=0, device="imu", frame=Frame.BODY_NED, gyro_rad_s=(0.1, 0, 0))
    assert est.process(g) == []
    est.process(AccelSample(t_ns=1, device="imu", frame=Frame.BODY_NED, accel_m_s2=(9, 9, 9),
                            flags=SampleFlag.SATURATED))
    assert est.process(g) == []
    assert est.diagnostics()["invalid"]["accel"] == 1
    est.process(AccelSample(t_ns=2, device="imu", frame=Frame.BODY_NED, accel_m_s2=REST))
    (e,) = est.process(GyroSample(t_ns=3, device="imu", frame=Frame.BODY_NED,
                                  gyro_rad_s=(0, 0, 0)))
    assert e.diagnostics["setup"] is True


@pytest.mark.parametrize("euler", [(-3.0, 5.0, 0.0), (40.0, -20.0, 0.0), (0.0, 80.0, 0.0)])
def test_setup_aligns_the_accelerometer_with_down_and_sets_no_yaw(euler) -> None:
    f = _rest_f(quat_from_euler_deg(*euler))
    q = setup_quaternion(tuple(-c / G0 for c in f))
    down = to_global(q, tuple(-c / G0 for c in f))
    assert np.allclose(down, (0.0, 0.0, 1.0), atol=1e-12)
    assert q[3] == 0.0


def test_band_keeps_full_gain_at_rest_and_drops_it_under_sustained_acceleration() -> None:
    est = ImuFilterEstimator()
    est.update((0, 0, 0), REST)
    for _ in range(200):
        q = est.update((0, 0, 0), REST)
    assert est._gain > 0.999
    for _ in range(20):  # 0.1 s of 0.5 g sideways: far outside the 0.2 g band
        est.update((0, 0, 0), (0.0, 0.5 * G0, -G0))
    assert est._gain < 0.2
    assert q is not None


def test_band_limits_tilt_error_under_sustained_acceleration() -> None:
    """1 s of 0.5 g sideways (a turn): the band leaves < 1/3 of the tilt a filter without it
    (sd_acc huge) picks up."""
    tilts = {}
    for sd in (0.2, 1e6):
        est = ImuFilterEstimator({"sd_acc_g": sd})
        est.update((0, 0, 0), REST)
        for _ in range(200):
            est.update((0, 0, 0), (0.0, 0.5 * G0, -G0))
        tilts[sd] = abs(est.update((0, 0, 0), REST) @ np.array([0, 1, 0, 0]))
    assert tilts[0.2] < tilts[1e6] / 3


def test_rotate_heading_turns_about_the_vertical_only() -> None:
    est = ImuFilterEstimator()
    est.update((0, 0, 0), _rest_f(quat_from_euler_deg(10.0, -20.0, 0.0)))
    before = euler_deg_from_quat(est.quaternion)
    est.rotate_heading(math.radians(30.0))
    after = euler_deg_from_quat(est.quaternion)
    assert after[0] == pytest.approx(before[0], abs=1e-9)
    assert after[1] == pytest.approx(before[1], abs=1e-9)
    assert after[2] - before[2] == pytest.approx(30.0, abs=1e-9)
    est.rotate_heading(0.1, small_angle=True)  # the library's approximation: 2 atan(0.05/0.9975)
    assert euler_deg_from_quat(est.quaternion)[2] - after[2] == pytest.approx(
        math.degrees(0.1), abs=0.01)


def test_frame_helpers_are_inverse_and_axes_are_rotation_columns_and_rows() -> None:
    q = quat_from_euler_deg(25.0, -10.0, 140.0)
    est = ImuFilterEstimator()
    est.set_state({**est.get_state(), "q": list(q)})
    v = np.array([1.0, -2.0, 0.5])
    assert np.allclose(est.to_local(est.to_global(v)), v, atol=1e-12)
    assert np.allclose(est.to_global(v), quat_to_matrix(q) @ v, atol=1e-12)
    r = quat_to_matrix(q)
    for i, axis in enumerate("xyz"):
        assert np.allclose(est.axis(axis, in_global=True), r[:, i], atol=1e-12)
        assert np.allclose(est.axis(axis, in_global=False), r[i, :], atol=1e-12)


def test_velocity_stays_at_rest_despite_accelerometer_bias() -> None:
    """A 0.05 g bias (inside the band) is absorbed: |v| < 1e-3 m/s over 10 s."""
    est = ImuFilterEstimator()
    biased = (0.05 * G0, 0.0, -G0)
    speeds = []
    for _ in range(2000):
        est.update((0, 0, 0), biased)
        speeds.append(np.linalg.norm(est.velocity_ned_m_s))
    assert max(speeds) < 1e-3


def test_velocity_integrates_with_the_trapezoidal_rule() -> None:
    """With the band and the target pull switched off by the state (huge variances) one step
    adds (a_last + a) dt / 2 exactly."""
    q = (1.0, 0.0, 0.0, 0.0)
    state = VelocityState(velocity=(1.0, 0.0, 0.0), accel_last=(2.0, 0.0, 0.0),
                          var_vel=1e30, var_acc=1e30)
    f = (4.0, 0.0, -G0)  # 4 m/s^2 north
    new = velocity_step(state, q, (0.0, 0.0, 0.0), f, 0.01, 0.2 * G0, 0.1 * G0)
    assert new.velocity[0] == pytest.approx(1.0 + (2.0 + 4.0) * 0.01 / 2, abs=1e-9)
    assert new.accel_last == pytest.approx((4.0, 0.0, 0.0), abs=1e-9)


def test_velocity_relaxes_to_the_target_at_rest() -> None:
    est = ImuFilterEstimator()
    est.update((0, 0, 0), REST)
    est.set_velocity_target((1.5, 0.0, 0.0))
    for _ in range(20):
        est.update((0, 0, 0), REST)
    assert np.allclose(est.velocity_ned_m_s, (1.5, 0.0, 0.0), atol=1e-6)


def test_state_round_trip_continues_identically() -> None:
    rng = np.random.default_rng(11)
    gyro = rng.normal(0, 0.3, (300, 3))
    accel = np.array(REST) + rng.normal(0, 3.0, (300, 3))
    ref = ImuFilterEstimator()
    whole = [ref.update(g, a) for g, a in zip(gyro, accel, strict=True)]
    a = ImuFilterEstimator()
    for g, f in zip(gyro[:120], accel[:120], strict=True):
        a.update(g, f)
    b = ImuFilterEstimator()
    b.set_state(json.loads(json.dumps(a.get_state())))
    rest = [b.update(g, f) for g, f in zip(gyro[120:], accel[120:], strict=True)]
    assert all(np.array_equal(x, y) for x, y in zip(rest, whole[120:], strict=True))
    assert np.array_equal(b.velocity_ned_m_s, ref.velocity_ned_m_s)
