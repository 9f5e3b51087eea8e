"""vario-kf3 as a pipeline estimator: inputs, down-sampling, units, skipping, state."""

from __future__ import annotations

import json
from typing import Any

import numpy as np
import pytest

import imuhal_filters.vario.plugin as vario_plugin
from imuhal.core.atmosphere import STANDARD_GRAVITY_M_S2, pressure_pa_at_altitude
from imuhal.core.frames import quat_from_euler_deg, quat_to_matrix
from imuhal.core.samples import AccelSample, Frame, PressureSample, SampleFlag
from imuhal.estimation.outputs import (
    AttitudeBlock,
    AttitudeEstimate,
    EstimateFlag,
    RejectedEstimate,
    VerticalEstimate,
)
from imuhal.plugins.manager import load_registry
from imuhal_filters.vario.kf3 import Kf3Mode
from imuhal_filters.vario.kf3_estimator import SETTLED_CLIMB_SIGMA_M_S, VarioKf3Estimator
from imuhal_filters.vario.kf3_settings import VarioKf3Settings, configured_core

IMU_DT_NS = 5_000_000  # 200 Hz
BARO_EVERY = 5  # 40 Hz barometer
Q_LEVEL = (1.0, 0.0, 0.0, 0.0)
AT_REST: dict[str, Any] = {"initial_climb_sigma_m_s": 0.01}
"""A board known to start at rest (the esp32 reference's 1 cm/s): every estimate speaks, so
these tests see the filter's mechanics; the start-up's withholding has its own tests."""


def _flight(seed: int, n_baro: int = 200) -> tuple[np.ndarray, np.ndarray]:
    """Seeded IMU-rate upward acceleration (m/s^2, bias 0.2 included) and baro altitude (m)."""
    rng = np.random.default_rng(seed)
    n_imu = n_baro * BARO_EVERY
    accel_up = 0.2 + rng.normal(0.0, 0.5, n_imu)
    z = 350.0 + np.cumsum(rng.normal(0.0, 0.02, n_baro)) + rng.normal(0.0, 0.3, n_baro)
    return accel_up, z


def _attitude(t_ns: int, accel_up: float | None, q: Any = Q_LEVEL, source: str = "ahrs"
              ) -> AttitudeEstimate:
    lin = None if accel_up is None else (0.0, 0.0, -accel_up)
    return AttitudeEstimate(t_ns=t_ns, source=source, q_body_to_ned=tuple(q),
                            linear_accel_ned_m_s2=lin)


def _pressure(t_ns: int, z_m: float, flags: SampleFlag = SampleFlag.OK) -> PressureSample:
    return PressureSample(t_ns=t_ns, device="baro", pressure_pa=pressure_pa_at_altitude(z_m),
                          flags=flags)


def _stream(accel_up: np.ndarray, z: np.ndarray) -> list[Any]:
    """Attitude estimates (with linear accel) at 200 Hz, a pressure sample after every 5th."""
    items: list[Any] = []
    for i, a in enumerate(accel_up):
        t = (i + 1) * IMU_DT_NS
        items.append(_attitude(t, float(a)))
        if (i + 1) % BARO_EVERY == 0:
            items.append(_pressure(t, float(z[(i + 1) // BARO_EVERY - 1])))
    return items


def _run(est: VarioKf3Estimator, items: list[Any]) -> list[VerticalEstimate]:
    out: list[VerticalEstimate] = []
    for item in items:
        out.extend(est.process(item))  # type: ignore[arg-type]
    return out


def _values(estimates: list[VerticalEstimate]) -> list[tuple[int, float, float, float | None]]:
    """What a vertical estimate says, without its diagnostics (which count skipped input)."""
    return [(e.t_ns, e.altitude_m, e.climb_m_s, e.accel_bias_m_s2) for e in estimates]


def test_registered_as_vario_kf3_through_the_plugin_hook() -> None:
    registry = load_registry(entry_point_plugins=False, extra=[("vario", vario_plugin)])
    assert registry.estimators.get("vario-kf3") is VarioKf3Estimator


def test_runs_once_per_baro_sample_on_the_mean_of_the_imu_accels_since_the_last_one() -> None:
    accel_up, z = _flight(seed=1)
    out = _run(VarioKf3Estimator(AT_REST), _stream(accel_up, z))
    assert len(out) == len(z)

    # The same filter driven by hand in cm: boxcar means of each 5 IMU samples, dt 25 ms,
    # and, as the references do, a step on the first sample too
    kf = configured_core(VarioKf3Settings(), float(z[0]))
    means = accel_up.reshape(-1, BARO_EVERY).mean(axis=1)
    for k in range(len(z)):
        kf.predict(means[k] * 100.0, 0.025)
        kf.update(z[k] * 100.0)
        if k == 0:
            continue
        assert out[k].altitude_m == pytest.approx(kf.z / 100.0, abs=1e-9)
        assert out[k].climb_m_s == pytest.approx(kf.v / 100.0, abs=1e-9)
        assert out[k].accel_bias_m_s2 == pytest.approx(kf.bias / 100.0, abs=1e-9)


def test_first_baro_sample_initialises_without_a_step() -> None:
    est = VarioKf3Estimator({**AT_REST, "initial_bias_m_s2": 0.1})
    (e,) = _run(est, [_attitude(1, 5.0), _pressure(2, 812.0)])
    assert (e.altitude_m, e.climb_m_s, e.accel_bias_m_s2) == (pytest.approx(812.0), 0.0, 0.1)
    assert e.source == "vario-kf3"


def test_accel_sample_with_attitude_quaternion_equals_ahrs_linear_accel() -> None:
    accel_up, z = _flight(seed=2, n_baro=80)
    q = quat_from_euler_deg(12.0, -7.0, 130.0)
    r = quat_to_matrix(q)
    linear = _stream(accel_up, z)
    raw: list[Any] = []
    for item in linear:
        if isinstance(item, AttitudeEstimate):
            # same vertical acceleration plus some horizontal: specific force = R^T (a - g)
            a_ned = np.array([0.3, -0.2, item.linear_accel_ned_m_s2[2]])  # type: ignore[index]
            f_body = r.T @ (a_ned - np.array([0.0, 0.0, STANDARD_GRAVITY_M_S2]))
            raw.append(_attitude(item.t_ns, None, q=q))
            raw.append(AccelSample(t_ns=item.t_ns, device="imu", frame=Frame.BODY_NED,
                                   accel_m_s2=tuple(f_body)))
        else:
            raw.append(item)
    out_linear = _run(VarioKf3Estimator(AT_REST), linear)
    est_raw = VarioKf3Estimator(AT_REST)
    out_raw = _run(est_raw, raw)
    assert est_raw.diagnostics()["accel_samples_without_attitude"] == 0
    np.testing.assert_allclose([e.climb_m_s for e in out_raw],
                               [e.climb_m_s for e in out_linear], rtol=0, atol=1e-9)
    # an accel sample before any quaternion is counted, not used
    early = VarioKf3Estimator(AT_REST)
    early.process(raw[1])
    assert early.diagnostics()["accel_samples_without_attitude"] == 1


def test_accel_samples_are_ignored_when_the_ahrs_supplies_linear_accel() -> None:
    accel_up, z = _flight(seed=3, n_baro=40)
    items = _stream(accel_up, z)
    with_raw: list[Any] = []
    for item in items:
        if isinstance(item, AttitudeEstimate):  # a raw sample that would add 9.8 m/s^2 up
            with_raw.append(AccelSample(t_ns=item.t_ns, device="imu", frame=Frame.BODY_NED,
                                        accel_m_s2=(0.0, 0.0, -2 * STANDARD_GRAVITY_M_S2)))
        with_raw.append(item)
    assert _values(_run(VarioKf3Estimator(AT_REST), with_raw)) == _values(
        _run(VarioKf3Estimator(AT_REST), items))


def test_attitude_source_selects_one_ahrs() -> None:
    accel_up, z = _flight(seed=4, n_baro=40)
    items = _stream(accel_up, z)
    noisy = [i for item in items for i in (
        [item, _attitude(item.t_ns, 50.0, source="other-ahrs")]
        if isinstance(item, AttitudeEstimate) else [item])]
    selective = VarioKf3Estimator({**AT_REST, "attitude_source": "ahrs"})
    assert _run(selective, noisy) == _run(VarioKf3Estimator(AT_REST), items)


def test_invalid_pressure_and_accel_samples_are_skipped_and_counted() -> None:
    accel_up, z = _flight(seed=5, n_baro=60)
    items = _stream(accel_up, z)
    polluted: list[Any] = []
    for item in items:
        polluted.append(item)
        if isinstance(item, PressureSample) and item.t_ns % (10 * BARO_EVERY * IMU_DT_NS) == 0:
            polluted.append(_pressure(item.t_ns + 1, 0.0, flags=SampleFlag.BUS_ERROR))
    est = VarioKf3Estimator(AT_REST)
    assert _values(_run(est, polluted)) == _values(_run(VarioKf3Estimator(AT_REST), items))
    assert est.diagnostics()["skipped_invalid"] == 6
    assert est.diagnostics()["fused"] == 60

    raw = VarioKf3Estimator(AT_REST)
    _run(raw, [_attitude(1, None),
               AccelSample(t_ns=2, device="imu", frame=Frame.BODY_NED, flags=SampleFlag.SATURATED),
               AccelSample(t_ns=3, device="imu", frame=Frame.SENSOR)])
    assert raw.diagnostics()["accel_samples_skipped_invalid"] == 1
    assert raw.diagnostics()["accel_samples_skipped_frame"] == 1


def test_interval_without_accel_predicts_zero_true_acceleration_and_is_counted() -> None:
    est = VarioKf3Estimator({**AT_REST, "initial_bias_m_s2": 0.5})
    _run(est, [_pressure(0, 100.0), _pressure(25_000_000, 100.0)])
    # a_meas taken as the bias: no climb appears from the bias alone
    assert est.get_state()["kf"]["x"][1] == pytest.approx(0.0, abs=1e-12)  # climb, cm/s
    assert est.diagnostics()["intervals_without_accel"] == 1


def test_an_interval_without_accel_widens_the_climb_rate_and_withholds_it() -> None:
    """Nothing measured the acceleration: the climb rate's variance grows by a g over the
    interval, and the estimate is withheld (UNSETTLED) until altitudes pin it down."""
    est = VarioKf3Estimator(AT_REST)
    out = _run(est, [_pressure(0, 100.0), _pressure(25_000_000, 100.0)])
    assert isinstance(out[-1], RejectedEstimate)
    assert out[-1].flags == EstimateFlag.UNSETTLED


def test_saved_state_restored_mid_interval_continues_exactly() -> None:
    accel_up, z = _flight(seed=6)
    items = _stream(accel_up, z)
    cut = 83 * (BARO_EVERY + 1) + 3  # mid-interval: the accel accumulator holds 3 samples
    a = VarioKf3Estimator({**AT_REST, "mode": "avario"})
    _run(a, items[:cut])
    snapshot = json.loads(json.dumps(a.get_state()))
    b = VarioKf3Estimator({**AT_REST, "mode": "avario"})
    b.set_state(snapshot)
    assert _run(b, items[cut:]) == _run(a, items[cut:])


def test_reset_forgets_everything() -> None:
    accel_up, z = _flight(seed=7, n_baro=20)
    est = VarioKf3Estimator(AT_REST)
    first = _run(est, _stream(accel_up, z))
    est.reset()
    assert _run(est, _stream(accel_up, z)) == first


def test_si_settings_reach_the_core_in_cm_units() -> None:
    default = configured_core(VarioKf3Settings(preset="reference"), 12.0)
    assert (default.z_meas_variance, default.accel_variance, default.bias_variance) == (
        300.0, 50_000.0, 1.0)
    assert default.z == pytest.approx(1200.0)
    custom = configured_core(VarioKf3Settings(
        mode=Kf3Mode.Y2021, altitude_variance_m2=0.02, accel_variance_m2_s4=3.0,
        bias_variance_m2_s4=1e-6, initial_bias_m_s2=0.1), 0.0)
    assert custom.z_meas_variance == pytest.approx(200.0)
    assert custom.accel_variance == pytest.approx(30_000.0)
    assert custom.bias_variance == pytest.approx(0.01)
    assert custom.bias == pytest.approx(10.0)
    np.testing.assert_allclose(np.diag(custom.P), [1500.0, 1500.0, 1500.0])


def _attitude_block(rows: list[AttitudeEstimate], with_accel: bool = True) -> AttitudeBlock:
    return AttitudeBlock(
        rows[0].source, np.array([e.t_ns for e in rows], np.int64),
        np.array([e.q_body_to_ned for e in rows]),
        np.array([e.linear_accel_ned_m_s2 for e in rows]) if with_accel else None,
        lambda: [{} for _ in rows])


@pytest.mark.parametrize("with_accel", [True, False], ids=["linear-accel", "attitude-only"])
def test_an_attitude_block_gives_what_its_rows_give_one_by_one(with_accel: bool) -> None:
    """``update_estimate_block`` (an AHRS's FIFO read as one block) leaves the filter as
    its rows through ``process()`` one by one leave it: the same vertical estimates at
    the next pressure samples, bit for bit, and the same state; another source's block is
    ignored as its rows would be."""
    accel_up, z = _flight(seed=3, n_baro=60)
    rng = np.random.default_rng(3)
    by_block, one_by_one = VarioKf3Estimator(AT_REST), VarioKf3Estimator(AT_REST)
    got: list[Any] = []
    want: list[Any] = []
    for k in range(len(z)):
        t0 = k * BARO_EVERY * IMU_DT_NS
        tilt = rng.normal(0.0, 10.0, (BARO_EVERY, 2))
        rows = [_attitude(t0 + (i + 1) * IMU_DT_NS,
                          float(accel_up[k * BARO_EVERY + i]) if with_accel else None,
                          quat_from_euler_deg(tilt[i, 0], tilt[i, 1], 0.0))
                for i in range(BARO_EVERY)]
        other = _attitude_block([_attitude(e.t_ns, 9.0, source="other") for e in rows])
        got += by_block.update_estimate_block(_attitude_block(rows, with_accel))
        got += by_block.update_estimate_block(other)
        for e in rows + other.rows():
            want += one_by_one.process(e)
        if with_accel:
            pressure = _pressure(rows[-1].t_ns, float(z[k]))
        else:  # without a linear acceleration the filter takes the accelerometer's
            accel = AccelSample(t_ns=rows[-1].t_ns, device="imu", frame=Frame.BODY_NED,
                                accel_m_s2=(0.0, 0.0, -STANDARD_GRAVITY_M_S2))
            got += by_block.process(accel)
            want += one_by_one.process(accel)
            pressure = _pressure(rows[-1].t_ns + 1, float(z[k]))
        got += by_block.process(pressure)
        want += one_by_one.process(pressure)
    assert not any(isinstance(e, AttitudeEstimate) for e in got)
    assert len(got) == len(z)
    assert [repr(e) for e in got] == [repr(e) for e in want]
    assert json.dumps(by_block.get_state()) == json.dumps(one_by_one.get_state())


def _climbing(climb_m_s: float, seconds: float) -> list[Any]:
    """Switched on in a steady, noise-free climb: level flight's zero vertical acceleration
    at 200 Hz, the altitude rising ``climb_m_s`` from 350 m at 40 Hz."""
    n = round(seconds * 200)
    return _stream(np.zeros(n), 350.0 + climb_m_s * np.arange(1, n // BARO_EVERY + 1) * 0.025)


def test_by_default_the_start_is_withheld_until_the_climb_sigma_is_under_its_bound() -> None:
    """Climb 0 at switch-on is a guess (sigma UNKNOWN_CLIMB_SIGMA_M_S, the board may fly):
    the estimates are withheld (UNSETTLED) until the filter's own climb sigma is under
    SETTLED_CLIMB_SIGMA_M_S, then every one speaks."""
    est = VarioKf3Estimator()
    out = _run(est, _climbing(0.0, 5.0))
    spoken = [i for i, e in enumerate(out) if isinstance(e, VerticalEstimate)]
    assert spoken and spoken == list(range(spoken[0], len(out)))
    assert all(isinstance(e, RejectedEstimate) and e.flags == EstimateFlag.UNSETTLED
               for e in out[:spoken[0]])
    assert out[spoken[0]].diagnostics["climb_sigma_m_s"] < SETTLED_CLIMB_SIGMA_M_S
    assert 0.5 < spoken[0] * 0.025 < 1.5  # about 0.9 s of altitudes at 40 Hz
    assert est.diagnostics()["withheld_unsettled"] == spoken[0]


@pytest.mark.parametrize("climb_m_s", [-3.0, 1.07, 5.0])
def test_a_start_in_flight_is_never_handed_out_off_the_climb(climb_m_s: float) -> None:
    """Switched on in a steady climb or sink: once the estimates speak, each is within
    2 settled sigmas (0.5 m/s) of the truth (the references' start trusted climb 0 to 1 cm/s,
    put the altitudes' slope into the bias and overshot), and after 5 s within 5 cm/s."""
    out = _run(VarioKf3Estimator(), _climbing(climb_m_s, 5.0))
    spoken = [e for e in out if isinstance(e, VerticalEstimate)]
    assert max(abs(e.climb_m_s - climb_m_s) for e in spoken) < 2 * SETTLED_CLIMB_SIGMA_M_S
    assert spoken[-1].climb_m_s == pytest.approx(climb_m_s, abs=0.05)


def test_the_reference_preset_starts_as_the_references_do() -> None:
    """``preset: reference`` reproduces the references' start (climb 0 to 1 cm/s, a board at
    rest): the first estimate speaks."""
    first = _run(VarioKf3Estimator({"preset": "reference"}), _climbing(0.0, 0.025))
    assert [type(e) for e in first] == [VerticalEstimate]
    assert first[0].diagnostics["climb_sigma_m_s"] == pytest.approx(0.01)
