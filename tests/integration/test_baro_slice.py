"""The first end-to-end slice: the MS5611 driver, through its register-level emulator (with
its datasheet noise and bias) on an emulated SPI bus, riding the ``elevator`` scenario (pure
vertical motion with a known profile), feeding the barometer-only vario filter. Checked
against the scenario's ground truth."""

from __future__ import annotations

import numpy as np
import pytest

from imuhal.emulation import open_emulated
from imuhal.estimation.outputs import VerticalEstimate
from imuhal.plugins.manager import Registry, load_registry
from imuhal.profile.bundled import default_profile_path
from imuhal.profile.loader import load_profile

RIDE_START_S = 5.0
CRUISE_S = [(8.0, 12.0), (23.0, 28.0)]
"""Constant-speed stretches of the up and down rides (1.6 m/s), away from the ramps."""
STILL_S = [(2.0, 5.0), (16.0, 20.0), (32.0, 40.0)]


@pytest.fixture(scope="module")
def ride() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    registry: Registry = load_registry()
    profile = load_profile(default_profile_path(), registry)
    # Only the barometer and the barometer-only filter: the slice under test.
    profile = profile.model_copy(update={"devices": {"baro": profile.devices["baro"]},
                                         "estimators": {"vario": profile.estimators["baro-only"]}})
    with open_emulated(profile, registry, scenario="elevator", seed=7) as p:
        rows = [(e.t_ns / 1e9, e.altitude_m, e.climb_m_s) for e in p.events(40.0)
                if isinstance(e, VerticalEstimate)]
        truth = [p.board.scenario.truth(t) for t, _, _ in rows]
    est = np.array(rows)
    return est, np.array([s.altitude_m for s in truth]), np.array([s.climb_m_s for s in truth])


def _window(t: np.ndarray, spans: list[tuple[float, float]]) -> np.ndarray:
    return np.any([(t >= a) & (t < b) for a, b in spans], axis=0)


def test_estimates_come_at_the_barometer_rate(ride) -> None:  # type: ignore[no-untyped-def]
    est, *_ = ride
    # the filter's start-up withholds its first 0.3-0.4 s (baro-vario settled_climb_sigma_m_s)
    assert 40 * 50 - 25 <= len(est) <= 40 * 50 + 2


def test_altitude_change_tracks_truth_within_30_cm(ride) -> None:  # type: ignore[no-untyped-def]
    # The MS5611's absolute error (+-1.5 mbar, about 12 m) is a constant offset: compare
    # changes from the first settled second.
    est, true_alt, _ = ride
    settled = est[:, 0] >= 1.0
    i0 = int(np.argmax(settled))
    err = (est[settled, 1] - est[i0, 1]) - (true_alt[settled] - true_alt[i0])
    assert np.max(np.abs(err)) < 0.3


def test_still_and_cruising_climb_rate_errors_are_small(ride) -> None:  # type: ignore[no-untyped-def]
    # Residual: 1.2 Pa RMS pressure noise (10 cm) differentiated and smoothed by the filter.
    est, _, true_climb = ride
    for spans in (STILL_S, CRUISE_S):
        m = _window(est[:, 0], spans)
        rms = float(np.sqrt(np.mean((est[m, 2] - true_climb[m]) ** 2)))
        assert rms < 0.15, (spans, rms)


def test_the_start_of_a_ride_is_seen_within_a_second(ride) -> None:  # type: ignore[no-untyped-def]
    # Barometer-only filters lag (the seed's reason for fusing the accelerometer): bound it.
    est, _, true_climb = ride
    t = est[:, 0]
    after = t > RIDE_START_S
    t_true = t[after][np.argmax(true_climb[after] > 0.8)]
    t_est = t[after][np.argmax(est[after, 2] > 0.8)]
    assert 0.0 <= t_est - t_true < 1.0
