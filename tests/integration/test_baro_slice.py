"""The first end-to-end slice: the MS5611 driver, through its register-level emulator on an
emulated SPI bus, flying the thermal scenario, feeding the barometer-only vario filter.
Checked against the scenario's ground truth."""

from __future__ import annotations

import numpy as np
import pytest

from imuhal.estimation.outputs import VerticalEstimate
from imuhal.pipeline import Pipeline
from imuhal.plugins.manager import Registry, load_registry
from imuhal.profile.loader import load_profile
from imuhal.profiles_dir import default_profile_path


@pytest.fixture(scope="module")
def slice_registry() -> Registry:
    return load_registry()


@pytest.fixture(scope="module")
def flight(slice_registry: Registry) -> tuple[np.ndarray, np.ndarray, np.ndarray, Pipeline]:
    profile = load_profile(default_profile_path(), slice_registry)
    # Only the barometer and the barometer-only filter: the slice under test.
    profile = profile.model_copy(update={"devices": {"baro": profile.devices["baro"]},
                                         "estimators": {"vario": profile.estimators["baro-only"]}})
    with Pipeline.open(profile, slice_registry, emulate="thermal") as p:
        rows = [(e.t_ns / 1e9, e.altitude_m, e.climb_m_s) for e in p.events(60.0)
                if isinstance(e, VerticalEstimate)]
        truth = [p.board.scenario.truth(t) for t, _, _ in rows]
    est = np.array(rows)
    true_alt = np.array([s.altitude_m for s in truth])
    true_climb = np.array([s.climb_m_s for s in truth])
    return est, true_alt, true_climb, p


def test_estimates_come_at_the_barometer_rate(flight) -> None:  # type: ignore[no-untyped-def]
    est, *_ = flight
    assert len(est) == pytest.approx(60 * 50, abs=2)


def test_altitude_change_tracks_truth_within_half_a_metre(flight) -> None:  # type: ignore[no-untyped-def]
    est, true_alt, _, p = flight
    origin = p.board.scenario.params.environment.origin_altitude_msl_m
    err = est[:, 1] - origin - true_alt
    assert np.max(np.abs(err[50:])) < 0.5  # after the first second


STEADY_WINDOWS_S = [(9.0, 15.0), (22.0, 35.0), (48.0, 60.0)]
"""Spans at least 4 s after a climb-rate change in the thermal schedule."""


def test_steady_climb_rate_rms_error_is_below_0_3_m_s(flight) -> None:  # type: ignore[no-untyped-def]
    # The residual is the MS5611's quantisation (about 1.2 Pa, 10 cm, at OSR 4096)
    # differentiated at 50 Hz and smoothed by the filter.
    est, _, true_climb, _ = flight
    for start, end in STEADY_WINDOWS_S:
        m = (est[:, 0] >= start) & (est[:, 0] < end)
        rms = float(np.sqrt(np.mean((est[m, 2] - true_climb[m]) ** 2)))
        assert rms < 0.3, (start, end, rms)


def test_a_thermal_entry_is_seen_within_a_second(flight) -> None:  # type: ignore[no-untyped-def]
    # Barometer-only filters lag (the seed's reason for fusing the accelerometer): bound it.
    est, _, true_climb, _ = flight
    t = est[:, 0]
    after = t > 14.0
    t_true = t[after][np.argmax(true_climb[after] > 0.7)]
    t_est = t[after][np.argmax(est[after, 2] > 0.7)]
    assert 0.0 <= t_est - t_true < 1.0


def test_no_sample_was_flagged(flight) -> None:  # type: ignore[no-untyped-def]
    *_, p = flight
    assert p.summary().flagged["baro"] == {}
