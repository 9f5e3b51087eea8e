"""baro-vario: the barometer-only altitude / climb-rate Kalman filter."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from pydantic import ValidationError

import imuhal_filters.vario.plugin as vario_plugin
from imuhal.core.atmosphere import pressure_pa_at_altitude
from imuhal.core.samples import PressureSample, SampleFlag
from imuhal.estimation.outputs import EstimateFlag, RejectedEstimate, VerticalEstimate
from imuhal.plugins.manager import load_registry
from imuhal_filters.vario.baro_estimator import BaroVarioEstimator

DATA = Path(__file__).resolve().parent.parent / "data" / "filters"
DT_NS = 25_000_000  # data set C: 40 Hz
AT_REST = {"initial_climb_sigma_m_s": 0.01}
"""A board known to start at rest: every estimate speaks from the first, so these tests see
the filter's mechanics; the default start-up's withholding has its own tests."""


def _pressure_samples(altitudes_m: np.ndarray, dt_ns: int = DT_NS) -> list[PressureSample]:
    return [PressureSample(t_ns=i * dt_ns, device="baro", pressure_pa=pressure_pa_at_altitude(z))
            for i, z in enumerate(altitudes_m)]


def _run(est: BaroVarioEstimator, samples: list[PressureSample]) -> list[VerticalEstimate]:
    out: list[VerticalEstimate] = []
    for s in samples:
        out.extend(est.process(s))  # type: ignore[arg-type]
    return out


def test_registered_as_baro_vario_through_the_plugin_hook() -> None:
    registry = load_registry(entry_point_plugins=False, extra=[("vario", vario_plugin)])
    assert registry.estimators.get("baro-vario") is BaroVarioEstimator


def test_first_valid_sample_initialises_altitude_with_zero_climb() -> None:
    est = BaroVarioEstimator(AT_REST)
    (e,) = _run(est, _pressure_samples(np.array([1234.5])))
    assert e.altitude_m == pytest.approx(1234.5, abs=1e-6)
    assert e.climb_m_s == 0.0
    assert e.accel_bias_m_s2 is None
    assert e.source == "baro-vario"


def test_tracks_a_steady_noise_free_climb_to_within_1_cm_per_s() -> None:
    t = np.arange(0, 30, 0.025)
    est = BaroVarioEstimator({"accel_noise_m_s2": 0.5, "altitude_noise_m": 0.2})
    out = _run(est, _pressure_samples(500.0 + 1.5 * t))
    assert out[-1].climb_m_s == pytest.approx(1.5, abs=0.01)
    assert out[-1].altitude_m == pytest.approx(500.0 + 1.5 * t[-1], abs=0.01)


def test_uses_sample_timestamps_for_dt() -> None:
    # The same climb sampled at 10 Hz instead of 40 Hz must give the same climb rate.
    t = np.arange(0, 30, 0.1)
    est = BaroVarioEstimator({"accel_noise_m_s2": 0.5})
    out = _run(est, _pressure_samples(100.0 - 2.0 * t, dt_ns=100_000_000))
    assert out[-1].climb_m_s == pytest.approx(-2.0, abs=0.01)


def test_climb_error_on_data_set_c_is_below_35_cm_per_s_rms() -> None:
    d = np.genfromtxt(DATA / "vario_C_first50s.csv", delimiter=",", names=True)
    # data set C starts at rest (5 s static)
    est = BaroVarioEstimator({**AT_REST, "accel_noise_m_s2": 3.0, "altitude_noise_m": 0.3})
    out = _run(est, _pressure_samples(d["z_baro_cm"] / 100.0))
    climb = np.array([e.climb_m_s for e in out])
    settled = np.arange(len(d)) >= 200  # after the 5 s static start
    rms = float(np.sqrt(np.mean((climb - d["v_true_cms"] / 100.0)[settled] ** 2)))
    # raw baro noise is 0.30 m at 40 Hz: finite differences alone would be ~17 m/s RMS
    assert rms < 0.35


def test_invalid_and_unusable_samples_are_skipped_and_counted() -> None:
    rng = np.random.default_rng(5)
    clean = _pressure_samples(200.0 + rng.normal(0.0, 0.3, 200))
    mixed: list[PressureSample] = []
    for i, s in enumerate(clean):
        mixed.append(s)
        if i % 20 == 5:  # a flagged sample and a nonsense one between good ones
            mixed.append(PressureSample(t_ns=s.t_ns + 1, device="baro", pressure_pa=1.0,
                                        flags=SampleFlag.CRC_ERROR))
            mixed.append(PressureSample(t_ns=s.t_ns + 2, device="baro", pressure_pa=float("nan")))
    est_mixed, est_clean = BaroVarioEstimator(AT_REST), BaroVarioEstimator(AT_REST)
    out_mixed, out_clean = _run(est_mixed, mixed), _run(est_clean, clean)
    assert [(e.altitude_m, e.climb_m_s) for e in out_mixed] == [
        (e.altitude_m, e.climb_m_s) for e in out_clean]
    assert est_mixed.diagnostics()["skipped_invalid"] == 20
    assert est_mixed.diagnostics()["fused"] == 200
    assert out_mixed[-1].diagnostics["skipped_invalid"] == 20


def test_sample_that_does_not_advance_time_is_skipped_and_counted() -> None:
    samples = _pressure_samples(np.array([10.0, 10.1, 10.2]))
    repeat = PressureSample(t_ns=samples[1].t_ns, device="baro", pressure_pa=samples[1].pressure_pa)
    est = BaroVarioEstimator()
    out = _run(est, [samples[0], samples[1], repeat, samples[2]])
    assert len(out) == 3
    assert est.diagnostics()["skipped_non_monotonic"] == 1


def test_gap_longer_than_max_gap_restarts_from_the_new_sample() -> None:
    est = BaroVarioEstimator({**AT_REST, "max_gap_s": 1.0})
    first = _pressure_samples(np.full(40, 50.0))
    late = PressureSample(t_ns=first[-1].t_ns + 3_000_000_000, device="baro",
                          pressure_pa=pressure_pa_at_altitude(80.0))
    (e,) = _run(est, [*first, late])[-1:]
    assert e.altitude_m == pytest.approx(80.0, abs=1e-6)
    assert e.climb_m_s == 0.0
    assert est.diagnostics()["restarts_after_gap"] == 1


def test_saved_state_restored_in_a_new_instance_continues_exactly() -> None:
    rng = np.random.default_rng(11)
    samples = _pressure_samples(300.0 + np.cumsum(rng.normal(0.0, 0.05, 400)))
    a = BaroVarioEstimator()
    _run(a, samples[:250])
    snapshot = json.loads(json.dumps(a.get_state()))
    b = BaroVarioEstimator()
    b.set_state(snapshot)
    assert _run(b, samples[250:]) == _run(a, samples[250:])


def test_reset_returns_to_the_uninitialised_state() -> None:
    est = BaroVarioEstimator(AT_REST)
    _run(est, _pressure_samples(np.array([10.0, 11.0, 12.0])))
    est.reset()
    (e,) = _run(est, _pressure_samples(np.array([99.0])))
    assert e.altitude_m == pytest.approx(99.0, abs=1e-6)
    assert est.diagnostics()["fused"] == 1


def test_by_default_the_start_is_withheld_until_the_climb_sigma_is_under_its_bound() -> None:
    """The board may be switched on flying: climb 0 is a guess (sigma 5 m/s), so the
    estimates are withheld (UNSETTLED) until the filter's climb sigma is under
    ``settled_climb_sigma_m_s``; then every one speaks."""
    t = np.arange(0, 3, 0.02)
    est = BaroVarioEstimator()
    out = _run(est, _pressure_samples(500.0 + 1.5 * t, dt_ns=20_000_000))
    spoken = [i for i, e in enumerate(out) if isinstance(e, VerticalEstimate)]
    assert spoken and spoken == list(range(spoken[0], len(out)))
    assert all(isinstance(e, RejectedEstimate) and e.flags == EstimateFlag.UNSETTLED
               for e in out[:spoken[0]])
    first = out[spoken[0]]
    assert isinstance(first, VerticalEstimate)
    assert first.diagnostics["climb_sigma_m_s"] < 0.4
    assert 0.1 < spoken[0] * 0.02 < 0.5  # withheld for a few tenths of a second at 50 Hz
    assert est.diagnostics()["withheld_unsettled"] == spoken[0]


def test_a_start_in_a_steady_climb_is_never_handed_out_as_climb_zero() -> None:
    """Switched on in a noise-free 1.5 m/s climb: once the estimates speak, each is within
    3 settled sigmas (1.2 m/s) of the truth and the last within 1 cm/s."""
    t = np.arange(0, 10, 0.02)
    out = _run(BaroVarioEstimator(), _pressure_samples(500.0 + 1.5 * t, dt_ns=20_000_000))
    spoken = [e for e in out if isinstance(e, VerticalEstimate)]
    assert max(abs(e.climb_m_s - 1.5) for e in spoken) < 3 * 0.4
    assert spoken[-1].climb_m_s == pytest.approx(1.5, abs=0.01)


def test_settings_reject_non_positive_noise() -> None:
    with pytest.raises(ValidationError):
        BaroVarioEstimator({"altitude_noise_m": 0.0})
    with pytest.raises(ValidationError):
        BaroVarioEstimator({"accel_noise_m_s2": -1.0})


def test_one_wrong_but_valid_pressure_does_not_move_the_seed_profiles_baro_only_vario() -> None:
    """Issue 26 item 8: the seed board's ``baro-only`` vario, given one pressure 300 Pa off
    (about 25 m; valid by design, docs/reliability.md), keeps its climb rate: the innovation
    gate rejects it. Ungated, the climb rate moved 5.6 m/s."""
    from imuhal.emulation import open_emulated
    from imuhal.emulation.faults import WrongPressure
    from imuhal.profile.bundled import default_profile_path
    from imuhal.profile.loader import load_profile

    registry = load_registry()
    profile = load_profile(default_profile_path(), registry)
    with open_emulated(profile, registry, scenario="static",
                       faults=[WrongPressure(device="baro", start_s=3.0, offset_pa=300.0)]) as p:
        climbs = [(e.t_ns / 1e9, e.climb_m_s, e.diagnostics["altitude_gated"])
                  for e in p.events(5.0)
                  if isinstance(e, VerticalEstimate) and e.source == "baro-only"]
    before = max(abs(c) for t, c, _ in climbs if 2.0 < t < 3.0)
    after = max(abs(c) for t, c, _ in climbs if 3.0 <= t < 5.0)
    assert sum(gated for _, _, gated in climbs) == 1
    assert after < max(2 * before, 0.2)
