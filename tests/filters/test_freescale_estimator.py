"""The freescale-9dof / freescale-6dof estimators: project units in, body -> NED out.

Fed dataset A (first 20 s, see test_freescale_conformance) as AccelSample (specific force,
m/s^2), GyroSample (rad/s) and MagSample (uT) in body NED, they must reproduce the reference
rows within 0.1 deg, whatever the order of the samples inside one tick.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

import imuhal_filters.freescale.plugin as freescale_plugin
from imuhal.core.atmosphere import STANDARD_GRAVITY_M_S2
from imuhal.core.frames import quat_multiply
from imuhal.core.samples import AccelSample, Frame, GyroSample, MagSample, Sample, SampleFlag
from imuhal.estimation.outputs import AttitudeEstimate
from imuhal.plugins.manager import load_registry
from imuhal_filters.freescale.estimator import Freescale6DofEstimator, Freescale9DofEstimator

DATA = Path(__file__).parent.parent / "data" / "filters"
DT_NS = 5_000_000
N_ROWS = 2000  # 10 s are enough here; the full slice is in the conformance tests


def _counts() -> np.ndarray:
    return np.loadtxt(DATA / "fsl_imu_A_counts.csv", delimiter=",", skiprows=2)[:N_ROWS]


def _tick(row: np.ndarray, *, order: str = "agm") -> list[Sample]:
    """The samples of one 200 Hz tick, in body NED and project units."""
    i = int(row[0])
    t = i * DT_NS
    force = tuple(-row[1:4] / 2048.0 * STANDARD_GRAVITY_M_S2)  # gravity positive -> force
    rate = tuple(np.radians(row[4:7] / 128.0))
    field = tuple(row[7:10] / 16.0)
    by_kind = {
        "a": AccelSample(t_ns=t, device="imu", frame=Frame.BODY_NED, accel_m_s2=force),
        "g": GyroSample(t_ns=t, device="imu", frame=Frame.BODY_NED, gyro_rad_s=rate),
        "m": MagSample(t_ns=t, device="imu", frame=Frame.BODY_NED, mag_ut=field),
    }
    return [by_kind[k] for k in order]


def _run(est: Freescale9DofEstimator | Freescale6DofEstimator, rows: np.ndarray,
         order: str = "agm") -> list[AttitudeEstimate]:
    out: list[AttitudeEstimate] = []
    for row in rows:
        for sample in _tick(row, order=order):
            out += [e for e in est.process(sample) if isinstance(e, AttitudeEstimate)]
    return out


def _reference(name: str) -> np.ndarray:
    ref = np.genfromtxt(DATA / f"{name}_first20s.csv", delimiter=",", names=True)
    return ref[(ref["kf_valid"] == 1) & (ref["idx"] < N_ROWS)]


def _angle_deg(a: tuple[float, ...] | np.ndarray, b: np.ndarray) -> float:
    d = quat_multiply(np.asarray(a) * [1, -1, -1, -1], b / np.linalg.norm(b))
    return math.degrees(2.0 * math.atan2(float(np.linalg.norm(d[1:])), abs(float(d[0]))))


@pytest.mark.parametrize(("cls", "name"), [(Freescale9DofEstimator, "fsl_9dof_gby_kalman_A"),
                                           (Freescale6DofEstimator, "fsl_6dof_gy_kalman_A")])
@pytest.mark.parametrize("order", ["agm", "gam", "mga"])
def test_estimator_reproduces_reference_in_project_units_in_any_sample_order(
        cls: type[Freescale9DofEstimator], name: str, order: str) -> None:
    estimates = _run(cls({"preset": "reference"}), _counts(), order=order)
    ref = _reference(name)
    assert [e.t_ns for e in estimates] == [int(i) * DT_NS for i in ref["idx"]]
    worst = max(_angle_deg(e.q_body_to_ned, np.array([r["q0"], r["q1"], r["q2"], r["q3"]]))
                for e, r in zip(estimates, ref, strict=True))
    assert worst < 0.1


def test_9dof_diagnostics_carry_offset_inclination_and_jamming_in_project_units() -> None:
    est = Freescale9DofEstimator({"preset": "reference"})
    last = _run(est, _counts())[-1]
    ref = _reference("fsl_9dof_gby_kalman_A")[-1]
    d = last.diagnostics
    np.testing.assert_allclose(
        d["gyro_offset_rad_s"],
        np.radians([ref["gbias_x_dps"], ref["gbias_y_dps"], ref["gbias_z_dps"]]), atol=2e-5)
    assert d["inclination_deg"] == pytest.approx(ref["incl_deg"], abs=0.01)
    assert d["mag_jamming"] is False
    assert d["euler_deg"]["psi"] == pytest.approx(ref["yaw_deg"], abs=0.1)
    assert d["kalman_steps"] == N_ROWS // 8
    assert est.diagnostics()["inclination_deg"] == d["inclination_deg"]


def test_linear_acceleration_is_near_zero_for_this_slow_motion() -> None:
    """Dataset A has no linear acceleration; the compensated output shows only noise."""
    estimates = _run(Freescale9DofEstimator(), _counts())
    lin = np.array([e.linear_accel_ned_m_s2 for e in estimates[25:]])
    assert np.sqrt(np.mean(lin**2)) < 0.15  # m/s^2: 2 mg noise plus small attitude errors


def test_first_kalman_step_emits_nothing_and_the_second_emits_an_estimate() -> None:
    est = Freescale9DofEstimator({"preset": "reference"})
    rows = _counts()
    assert _run(est, rows[:8]) == []
    assert est.diagnostics()["kalman_steps"] == 1
    second = _run(est, rows[8:16])
    assert len(second) == 1 and second[0].t_ns == 15 * DT_NS


def test_without_reference_start_up_the_first_window_already_emits() -> None:
    est = Freescale9DofEstimator({"initialise_on_first_step": False})
    out = _run(est, _counts()[:8])
    assert [e.t_ns for e in out] == [7 * DT_NS]


def test_windows_without_accel_are_dropped_and_stale_accel_is_reused_but_counted() -> None:
    """A full gyro window waits for an accel sample at or after its last gyro sample; if the
    next gyro sample comes first, the window runs on the last accel reading (the reference
    reuses it too) or, with none yet, is dropped."""
    est = Freescale6DofEstimator({"initialise_on_first_step": False})
    rows = _counts()[:33]
    assert _run(est, rows[:16], order="g") == []  # window 0 dropped, window 1 waits
    assert [e.t_ns for e in _run(est, rows[16:24], order="ag")] == [15 * DT_NS, 23 * DT_NS]
    assert [e.t_ns for e in _run(est, rows[24:33], order="g")] == [31 * DT_NS]
    diag = est.diagnostics()
    assert diag["windows_without_accel_or_mag"] == 1
    assert diag["windows_with_stale_accel_or_mag"] == 1


def test_invalid_samples_are_skipped_and_counted_without_advancing_the_window() -> None:
    est = Freescale6DofEstimator({"preset": "reference"})
    rows = _counts()[:16]
    bad = GyroSample(t_ns=1, device="imu", frame=Frame.BODY_NED, gyro_rad_s=(0.0, 0.0, 0.0),
                     flags=SampleFlag.SATURATED)
    nan = AccelSample(t_ns=1, device="imu", frame=Frame.BODY_NED,
                      accel_m_s2=(math.nan, 0.0, -9.8))
    assert est.process(bad) == [] and est.process(nan) == []
    out = _run(est, rows)
    diag = est.diagnostics()
    assert diag["skipped_invalid"] == 2
    assert diag["gyro_samples"] == 16 and diag["kalman_steps"] == 2
    assert [e.t_ns for e in out] == [15 * DT_NS]


def test_samples_not_in_body_frame_are_refused_and_counted() -> None:
    est = Freescale9DofEstimator()
    s = GyroSample(t_ns=0, device="imu", frame=Frame.SENSOR, gyro_rad_s=(0.0, 0.0, 0.0))
    assert est.process(s) == []
    assert est.diagnostics()["skipped_not_body_frame"] == 1
    assert est.diagnostics()["gyro_samples"] == 0


def test_6dof_ignores_magnetometer_samples() -> None:
    rows = _counts()[:400]
    with_mag = _run(Freescale6DofEstimator(), rows, order="agm")
    without = _run(Freescale6DofEstimator(), rows, order="ag")
    assert [e.q_body_to_ned for e in with_mag] == [e.q_body_to_ned for e in without]


def test_state_round_trips_through_json_and_continues_identically() -> None:
    rows = _counts()[:800]
    straight = Freescale9DofEstimator()
    expected = _run(straight, rows)
    first = Freescale9DofEstimator()
    head = _run(first, rows[:403])  # mid-window: 3 gyro samples buffered
    state = json.loads(json.dumps(first.get_state()))
    resumed = Freescale9DofEstimator()
    resumed.set_state(state)
    tail = _run(resumed, rows[403:])
    assert [e.q_body_to_ned for e in head + tail] == [e.q_body_to_ned for e in expected]


def test_oversample_ratio_sets_the_kalman_rate() -> None:
    """Ratio 4 at 200 Hz: a Kalman step every 4 gyro samples (50 Hz); still tracks."""
    rows = _counts()[:1000]
    est = Freescale9DofEstimator({"preset": "reference", "oversample_ratio": 4})
    estimates = _run(est, rows)
    assert len(estimates) == 1000 // 4 - 1
    ref = _reference("fsl_9dof_gby_kalman_A")
    at_end = ref[ref["idx"] == 999][0]
    assert _angle_deg(estimates[-1].q_body_to_ned,
                      np.array([at_end["q0"], at_end["q1"], at_end["q2"], at_end["q3"]])) < 1.0


def test_plugin_registers_both_estimators() -> None:
    registry = load_registry(entry_point_plugins=False, extra=[("freescale", freescale_plugin)])
    assert registry.estimators.get("freescale-9dof") is Freescale9DofEstimator
    assert registry.estimators.get("freescale-6dof") is Freescale6DofEstimator


def test_settings_reject_unknown_and_out_of_range_values() -> None:
    with pytest.raises(ValueError):
        Freescale9DofEstimator({"oversample_ratio": 0})
    with pytest.raises(ValueError):
        Freescale9DofEstimator({"no_such_setting": 1})
    with pytest.raises(ValueError):
        Freescale6DofEstimator({"coordinate_system": "enu"})
