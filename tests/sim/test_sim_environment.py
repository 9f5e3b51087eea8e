"""Environment: ISA pressure against published values, weather, temperature, field."""

from __future__ import annotations

import math

import numpy as np
import pytest

from imuhal.sim.environment import ENVIRONMENT_PRESETS, Environment

SEA = Environment(origin_altitude_msl_m=0.0)


@pytest.mark.parametrize(("altitude_m", "pressure_pa"),
                         [(0.0, 101_325.0), (1000.0, 89_874.6), (2000.0, 79_495.2)])
def test_standard_atmosphere_matches_published_pressures(altitude_m, pressure_pa):
    # ISA tables (ICAO Doc 7488): 1013.25, 898.746, 794.952 hPa; within 1 Pa.
    assert SEA.pressure_pa(altitude_m, 0.0) == pytest.approx(pressure_pa, abs=1.0)


def test_origin_altitude_and_sea_level_pressure_shift_the_curve():
    env = Environment(origin_altitude_msl_m=1000.0, sea_level_pa=101_325.0)
    assert env.pressure_pa(1000.0, 0.0) == pytest.approx(79_495.2, abs=1.0)
    low = Environment(origin_altitude_msl_m=0.0, sea_level_pa=100_000.0)
    assert low.pressure_pa(0.0, 0.0) == pytest.approx(100_000.0)


def test_weather_drifts_the_sea_level_pressure():
    env = Environment(origin_altitude_msl_m=0.0, pressure_drift_pa_per_hour=-120.0,
                      weather_amplitude_pa=50.0, weather_period_s=7200.0)
    assert env.sea_level_pa_at(0.0) == pytest.approx(101_325.0)
    # After 30 min: trend -60 Pa, sinusoid at a quarter period +50 Pa.
    assert env.sea_level_pa_at(1800.0) == pytest.approx(101_325.0 - 60.0 + 50.0)


def test_board_warms_up_above_the_air_temperature():
    env = Environment(origin_altitude_msl_m=0.0, board_warmup_degc=8.0, board_warmup_tau_s=100.0)
    assert env.temperature_degc(0.0) == pytest.approx(15.0)
    assert env.temperature_degc(0.0, 100.0) == pytest.approx(15.0 + 8.0 * (1 - math.exp(-1)))
    assert env.temperature_degc(1000.0) == pytest.approx(15.0 - 6.5)


def test_field_has_the_configured_intensity_dip_and_declination():
    env = Environment.preset("mid-latitude")
    b = env.magnetic_field_ned_ut()
    assert np.linalg.norm(b) == pytest.approx(48.5)
    assert math.degrees(math.atan2(b[2], math.hypot(b[0], b[1]))) == pytest.approx(64.0)
    assert math.degrees(math.atan2(b[1], b[0])) == pytest.approx(4.0)


def test_presets_cover_the_seed_site_and_reject_unknown_names():
    assert {"bangalore", "mid-latitude"} <= set(ENVIRONMENT_PRESETS)
    assert Environment.preset("bangalore").inclination_deg == pytest.approx(13.0)
    assert Environment.preset("bangalore", sea_level_pa=100_900.0).sea_level_pa == 100_900.0
    with pytest.raises(ValueError, match="known"):
        Environment.preset("atlantis")
