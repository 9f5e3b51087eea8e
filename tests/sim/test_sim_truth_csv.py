"""Ground-truth CSV: documented columns, exact round trip, atomic writes, replay."""

from __future__ import annotations

import numpy as np
import pytest

from imuhal.sim.magnet import MagnetScenario
from imuhal.sim.recorded import RecordedMotion, ReplayScenario
from imuhal.sim.thermal import ThermalScenario
from imuhal.sim.truth_csv import (
    COLUMNS,
    read_truth_csv,
    record_truth,
    truth_states_from_columns,
    write_truth_csv,
)


def test_round_trip_is_exact(tmp_path):
    s = MagnetScenario(seed=4)
    times = np.arange(0.0, 40.0, 0.25)
    path = record_truth(tmp_path / "truth.csv", s, times)
    cols, meta = read_truth_csv(path)
    assert tuple(cols) == COLUMNS
    assert meta["scenario"] == "magnet" and meta["seed"] == "4"
    assert meta["format"] == "imuhal-truth v1"
    back = truth_states_from_columns(cols)
    for t, b in zip(times, back, strict=True):
        a = s.truth(float(t))
        np.testing.assert_array_equal(a.q_body_to_ned, b.q_body_to_ned)
        np.testing.assert_array_equal(a.specific_force_body_m_s2, b.specific_force_body_m_s2)
        np.testing.assert_array_equal(a.position_ned_m, b.position_ned_m)
        np.testing.assert_array_equal(a.magnetic_field_body_ut, b.magnetic_field_body_ut)
        np.testing.assert_array_equal(a.magnetic_disturbance_ned_ut,
                                      b.magnetic_disturbance_ned_ut)
        assert a.pressure_pa == b.pressure_pa and a.temperature_degc == b.temperature_degc


def test_derived_columns_agree_with_the_state(tmp_path):
    s = ThermalScenario(seed=1)
    path = record_truth(tmp_path / "t.csv", s, [30.0])
    cols, _ = read_truth_csv(path)
    tr = s.truth(30.0)
    assert cols["altitude_m"][0] == tr.altitude_m == -cols["pd_m"][0]
    assert cols["climb_m_s"][0] == -cols["vd_m_s"][0]
    assert (cols["roll_deg"][0], cols["pitch_deg"][0], cols["yaw_deg"][0]) == tr.euler_deg
    assert np.isnan(cols["dist_n_ut"][0])          # no disturbance in this scenario


def test_write_replaces_atomically_and_leaves_no_temp_file(tmp_path):
    target = tmp_path / "out" / "truth.csv"
    s = ThermalScenario()
    write_truth_csv(target, [s.truth(0.0)])
    first = target.read_text()
    write_truth_csv(target, [s.truth(0.0), s.truth(1.0)])
    assert target.read_text() != first
    assert sorted(p.name for p in target.parent.iterdir()) == ["truth.csv"]


def test_failed_write_keeps_the_old_file(tmp_path):
    target = tmp_path / "truth.csv"
    s = ThermalScenario()
    write_truth_csv(target, [s.truth(0.0)])
    before = target.read_text()

    def broken():
        yield s.truth(1.0)
        raise RuntimeError("simulated crash mid-recording")

    with pytest.raises(RuntimeError):
        write_truth_csv(target, broken())
    assert target.read_text() == before
    assert [p.name for p in tmp_path.iterdir()] == ["truth.csv"]


def test_replay_reproduces_the_recording_at_its_samples(tmp_path):
    s = ThermalScenario(seed=3)
    times = np.arange(0.0, 30.0, 0.1)
    path = record_truth(tmp_path / "rec.csv", s, times)
    replay = ReplayScenario({"path": str(path)})
    assert replay.duration_s == pytest.approx(times[-1])
    for t in times[::17]:
        a, b = s.truth(float(t)), replay.truth(float(t))
        assert abs(a.q_body_to_ned @ b.q_body_to_ned) == pytest.approx(1.0, abs=1e-12)
        np.testing.assert_allclose(b.position_ned_m, a.position_ned_m, atol=1e-9)
        np.testing.assert_allclose(b.velocity_ned_m_s, a.velocity_ned_m_s, atol=1e-9)
    # Between samples the interpolation stays close to the original (smooth flight).
    mid = replay.truth(12.05)
    np.testing.assert_allclose(mid.position_ned_m, s.truth(12.05).position_ned_m, atol=2e-3)


def test_replayed_trajectory_is_kinematically_consistent(tmp_path, consistency):
    # The rate is constant and the acceleration linear within each recorded interval (they
    # may jump at the samples), so: integrate inside intervals, check continuity across.
    s = ThermalScenario(seed=3)
    times = np.arange(0.0, 20.0, 0.2)
    path = record_truth(tmp_path / "rec.csv", s, times)
    motion = RecordedMotion.from_truth_csv(str(path))
    eps = 1e-9
    for t0, t1 in zip(times[:-1:9], times[1::9], strict=True):
        err = consistency(motion.kinematics, t1 - eps, (t1 - t0 - 2 * eps) / 20,
                          motion.gravity_m_s2, t_start=t0 + eps)
        assert err.attitude_rad < 1e-7     # the acos angle measure bottoms out near 4e-8
        assert err.velocity_m_s < 1e-10
        assert err.position_m < 1e-10
    for t in times[1:-1:7]:
        before, at = motion.kinematics(t - eps), motion.kinematics(t)
        np.testing.assert_allclose(before.q_body_to_ned, at.q_body_to_ned, atol=1e-7)
        np.testing.assert_allclose(before.velocity_ned_m_s, at.velocity_ned_m_s, atol=1e-7)
        np.testing.assert_allclose(before.position_ned_m, at.position_ned_m, atol=1e-7)
