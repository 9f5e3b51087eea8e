"""The "decoupled" estimator (VQF's method in imuhal): what each of its parts must do.

Synthetic boards at rest (tests/filters/ahrs_cases.py: 200 Hz, small white noise); the aligned
start, full-scale rejection and turn compensation are covered with every AHRS in
test_ahrs_alignment.py, test_ahrs_limits.py and test_ahrs_turns.py.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
from tests.filters.ahrs_cases import FIELD_NED_UT, at_rest, attitude, error_deg, run
from tests.filters.decoupled_flight_motion import flight
from tests.filters.decoupled_motion import Motion, hand_motion, tilt_error_deg

from imuhal.core.samples import GyroSample, MagSample, Sample
from imuhal.evaluate.metrics import rmse_deg
from imuhal_filters.decoupled.estimator import DecoupledEstimator
from imuhal_filters.decoupled.smoother import clean_field, field_weights

BIAS_RAD_S = (0.01, -0.015, 0.008)
"""About 0.6-0.9 deg/s per axis: an uncalibrated MEMS gyro."""


def _with_gyro_bias(samples: list[Sample]) -> list[Sample]:
    return [dataclasses.replace(s, gyro_rad_s=tuple(
        g + b for g, b in zip(s.gyro_rad_s, BIAS_RAD_S, strict=True)))
            if isinstance(s, GyroSample) else s for s in samples]


def _heading_deg(q: tuple[float, ...]) -> float:
    w, x, y, z = q
    return math.degrees(math.atan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z)))


def test_gyro_bias_is_estimated_at_rest_and_the_attitude_holds() -> None:
    q_true = attitude(10.0, -5.0, 30.0)
    est = DecoupledEstimator({"sample_period_s": 0.005})
    out = run(est, iter(_with_gyro_bias(list(at_rest(q_true, 20.0)))))
    assert out[-1].diagnostics["rest_detected"]
    bias = np.array(out[-1].diagnostics["gyro_bias_rad_s"])
    assert np.abs(bias - BIAS_RAD_S).max() < 0.001
    assert error_deg("decoupled", out[-1], q_true) < 1.0


def test_without_rest_bias_estimation_the_same_bias_turns_the_heading() -> None:
    # the check above can fail: a filter that ignored the bias would drift this much
    q_true = attitude(0.0, 0.0, 0.0)
    est = DecoupledEstimator({"sample_period_s": 0.005, "use_mag": False,
                              "rest_min_s": 1e6})
    out = run(est, iter(_with_gyro_bias(list(at_rest(q_true, 20.0)))))
    assert abs(_heading_deg(out[-1].q_body_to_ned)) > 5.0


def test_a_magnetic_disturbance_is_detected_and_does_not_turn_the_heading() -> None:
    q_true = attitude(0.0, 0.0, 0.0)
    samples = list(at_rest(q_true, 20.0))
    # a magnet next to the board from 5 s on: +30 uT along body y (the field turns 40 deg)
    disturbed = [dataclasses.replace(s, mag_ut=(s.mag_ut[0], s.mag_ut[1] + 30.0, s.mag_ut[2]))
                 if isinstance(s, MagSample) and s.t_ns >= 5e9 else s for s in samples]
    est = DecoupledEstimator({"sample_period_s": 0.005})
    out = run(est, iter(disturbed))
    late = [e for e in out if e.t_ns >= 6e9]
    assert all(e.diagnostics["mag_disturbed"] for e in late[:: 100])
    assert abs(_heading_deg(out[-1].q_body_to_ned)) < 1.0
    undefended = run(DecoupledEstimator({"sample_period_s": 0.005, "mag_norm_th": 10.0,
                                         "mag_dip_th_deg": 90.0}), iter(disturbed))
    assert abs(_heading_deg(undefended[-1].q_body_to_ned)) > 20.0


def test_a_lasting_new_field_becomes_the_reference() -> None:
    samples = list(at_rest(attitude(0.0, 0.0, 0.0), 12.0))
    moved = [dataclasses.replace(s, mag_ut=tuple(0.7 * np.asarray(s.mag_ut)))
             if isinstance(s, MagSample) and s.t_ns >= 2e9 else s for s in samples]
    out = run(DecoupledEstimator({"sample_period_s": 0.005, "mag_new_s": 5.0}), iter(moved))
    assert out[int(4e9 / 5e6)].diagnostics["mag_disturbed"]
    assert not out[-1].diagnostics["mag_disturbed"]


def test_offline_mode_smooths_a_whole_recording_and_refuses_to_run_live() -> None:
    q_true = attitude(20.0, 10.0, -40.0)
    samples = _with_gyro_bias(list(at_rest(q_true, 6.0)))
    gyro = np.array([s.gyro_rad_s for s in samples if isinstance(s, GyroSample)])
    accel = np.array([s.accel_m_s2 for s in samples if type(s).__name__ == "AccelSample"])
    mag = np.array([s.mag_ut for s in samples if isinstance(s, MagSample)])
    est = DecoupledEstimator({"sample_period_s": 0.005, "offline": True})
    q = est.smooth(gyro, accel, mag)
    assert q.shape == (gyro.shape[0], 4)
    np.testing.assert_allclose(np.linalg.norm(q, axis=1), 1.0, atol=1e-12)
    err = np.degrees(2 * np.arccos(np.minimum(1.0, np.abs(q @ q_true))))
    assert err.max() < 1.5  # the bias is learnt after 1.5 s of rest: about 1.2 deg of heading
    try:
        run(est, iter(samples[:30]))
    except ValueError as exc:
        assert "offline" in str(exc)
    else:
        raise AssertionError("offline: true ran live")


def test_state_round_trips_and_continues_identically() -> None:
    samples = _with_gyro_bias(list(at_rest(attitude(5.0, 5.0, 5.0), 4.0)))
    a = DecoupledEstimator({"sample_period_s": 0.005})
    run(a, iter(samples[:1800]))
    b = DecoupledEstimator({"sample_period_s": 0.005})
    b.set_state(a.get_state())
    qa = run(a, iter(samples[1800:]))[-1].q_body_to_ned
    qb = run(b, iter(samples[1800:]))[-1].q_body_to_ned
    assert qa == qb
    assert FIELD_NED_UT.shape == (3,)


def test_defaults_detect_manoeuvres_and_preset_handheld_trusts_every_reading() -> None:
    defaults = DecoupledEstimator().settings
    assert (defaults.accel_soft_gate_g, defaults.tau_acc_s) == (None, 3.0)
    assert defaults.manoeuvre_speed_m_s == 8.0
    assert defaults.innovation_speed_m_s is None
    handheld = DecoupledEstimator({"preset": "handheld"}).settings
    assert handheld.accel_soft_gate_g is None
    assert handheld.innovation_speed_m_s is None
    assert handheld.manoeuvre_speed_m_s is None
    assert handheld.tau_acc_s == 3.0
    flight = DecoupledEstimator({"preset": "flight"}).settings
    assert (flight.accel_soft_gate_g, flight.manoeuvre_speed_m_s) == (0.02, None)
    adaptive = DecoupledEstimator({"preset": "adaptive"}).settings
    assert (adaptive.accel_soft_gate_g, adaptive.innovation_speed_m_s) == (None, 1.0)


def test_after_an_accelerometer_gap_in_a_turns_roll_in_the_detectors_start_again() -> None:
    # the accelerometer silent for 0.8 s while the aeroplane rolls into a 30 deg/s turn (as
    # a clipped pull-up's readings are flagged): the manoeuvre detector's window saw only
    # the roll-in's start, the readings after the gap are the steady turn's. Its window
    # started again (half its velocity kept) it closes on them within the window; judged
    # by its memory of before the gap it took them as a hand's (1.24 deg RMS after the gap)
    m = flight(10.0, turn_deg_s=30.0, roll_360=False)
    gap = (m.t_s >= 7.0) & (m.t_s < 7.8)
    est = DecoupledEstimator({"sample_period_s": m.dt_s, "use_mag": False})
    q = np.array([est.update(g, None if silent else a, None, m.dt_s) for g, a, silent in
                  zip(m.gyro_rad_s, m.accel_m_s2, gap, strict=True)])
    after = m.t_s >= 7.8
    tilt = tilt_error_deg(q[after], m.q_true[after])
    assert float(np.sqrt(np.mean(tilt ** 2))) < 1.0  # measured 0.67


def _online(settings: dict, m: Motion, use_mag: bool) -> tuple[np.ndarray, DecoupledEstimator]:
    est = DecoupledEstimator({"sample_period_s": m.dt_s, "use_mag": use_mag,
                              "preset": "handheld", **settings})
    q = np.array([est.update(g, a, b, m.dt_s) for g, a, b in
                  zip(m.gyro_rad_s, m.accel_m_s2, m.mag_ut, strict=True)])
    return q, est


def _rms(x: np.ndarray) -> float:
    return float(np.sqrt(np.mean(x[500:] ** 2)))  # after the first 5 s


def test_gyro_bias_is_learnt_in_motion_from_the_inclination_corrections() -> None:
    # a minute of turning and shaking, never at rest: only the motion updates see the bias;
    # the body's x and y axes sweep the horizontal, so their bias is observable
    m = hand_motion(60.0, BIAS_RAD_S)
    q, est = _online({}, m, use_mag=False)
    # the saved state: with the compiled per-sample step the kernel object is written back
    # only when asked (``get_state``), so its attribute alone can be stale
    bias = np.array(est.get_state()["filter"]["bias"])
    assert np.abs(bias[:2] - BIAS_RAD_S[:2]).max() < 0.004  # 0.23 deg/s, of 0.6-0.9
    q_rest_only, _ = _online({"motion_bias": False}, m, use_mag=False)
    assert _rms(tilt_error_deg(q, m.q_true)) < 0.6 * _rms(tilt_error_deg(q_rest_only, m.q_true))


def test_offline_smoother_is_more_accurate_than_the_forward_filter() -> None:
    m = hand_motion(30.0, BIAS_RAD_S)
    for use_mag in (False, True):
        q_live, _ = _online({}, m, use_mag)
        q_off = DecoupledEstimator({"sample_period_s": m.dt_s, "use_mag": use_mag,
                                    "preset": "handheld", "offline": True}).smooth(
            m.gyro_rad_s, m.accel_m_s2, m.mag_ut)
        live, off = tilt_error_deg(q_live, m.q_true), tilt_error_deg(q_off, m.q_true)
        assert _rms(off) < 0.5 * _rms(live)
        if use_mag:
            def total(q: np.ndarray) -> np.ndarray:
                return np.degrees(2 * np.arccos(np.minimum(1.0, np.abs(np.sum(q * m.q_true,
                                                                                axis=1)))))
            assert _rms(total(q_off)) < 0.5 * _rms(total(q_live))


def test_offline_trusts_the_field_only_in_long_undisturbed_stretches_away_from_disturbances(
) -> None:
    dt = 0.1
    disturbed = np.zeros(200, dtype=bool)  # 20 s
    disturbed[50:60] = True   # a disturbance at 5-6 s
    disturbed[63:100] = True  # a chance pass at 6.0-6.3 s, then disturbed to 10 s
    trusted = clean_field(disturbed, min_clean_s=5.0, margin_s=2.0, dt=dt)
    assert trusted[:30].all()  # the recording's start needs no margin
    assert not trusted[30:120].any()  # 2 s either side, and the 0.3 s pass
    assert trusted[120:].all()  # to the recording's end
    assert not clean_field(disturbed[:130], 5.0, 2.0, dt)[100:].any()  # 3 s: too short


def test_offline_field_weight_falls_with_the_deviation_from_the_recordings_reference() -> None:
    ref = np.array([20.0, 0.0, 44.0])
    m = np.array([ref, ref, 1.1 * ref, ref + np.array([0.0, 0.0, 20.0])])
    w = field_weights(m, np.array([True, True, True, False]), norm_th=0.1,
                      dip_th_rad=math.radians(10.0))
    assert w[0] == w[1] == 1.0  # the reference is the trusted samples' median
    assert abs(w[2] - 0.5) < 1e-9  # a norm off by the threshold: half the gain
    assert w[3] == 0.0  # not trusted: never fused


def test_offline_heading_is_not_pulled_by_an_attached_magnet_s_approach_and_chance_passes(
) -> None:
    # a magnet fixed to the turning board (body-frame field, 15 / -7.5 / 5 uT, 3 s ramps in
    # and out): while it comes and goes the field deviates below the thresholds, and as
    # the board turns some readings pass the norm and dip check by chance
    m = hand_motion(40.0, BIAS_RAD_S)
    t = np.arange(len(m.q_true)) * m.dt_s
    s = np.clip((t - 10.0) / 3.0, 0.0, 1.0) * np.clip((28.0 - t) / 3.0, 0.0, 1.0)
    mag = m.mag_ut + s[:, None] * np.array([12.5, -7.5, 5.0])

    def heading_rms(settings: dict) -> float:
        q = DecoupledEstimator({"sample_period_s": m.dt_s, "preset": "handheld",
                                "offline": True, **settings}).smooth(
            m.gyro_rad_s, m.accel_m_s2, mag)
        return rmse_deg(q, m.q_true).heading_deg

    guarded = heading_rms({})
    assert guarded < 2.0
    # every reading the check passes fused: the magnet turns the heading
    assert heading_rms({"mag_min_clean_s": 0.0, "mag_margin_s": 0.0}) > 1.25 * guarded
