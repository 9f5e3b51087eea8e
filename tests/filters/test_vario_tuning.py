"""estimate_altitude_variance: the seed's way of finding sigma_zmeas^2."""

from __future__ import annotations

import numpy as np
import pytest

from imuhal_filters.vario.tuning import estimate_altitude_variance


def test_recovers_the_noise_variance_of_2_s_of_baro_at_rest_within_35_percent() -> None:
    # 80 samples: the relative standard error of a variance is sqrt(2/79) ~ 16 %
    rng = np.random.default_rng(21)
    z = 412.0 + rng.normal(0.0, 0.3, 80)
    assert estimate_altitude_variance(z, sample_rate_hz=40.0) == pytest.approx(0.09, rel=0.35)


def test_matches_the_unbiased_sample_variance() -> None:
    z = [1.0, 2.0, 4.0, 7.0, 11.0, 16.0, 22.0, 29.0, 37.0, 46.0]
    assert estimate_altitude_variance(z, 40.0) == pytest.approx(float(np.var(z, ddof=1)))


def test_refuses_more_than_5_s_because_pressure_drifts() -> None:
    with pytest.raises(ValueError, match="drifts"):
        estimate_altitude_variance(np.zeros(201), sample_rate_hz=40.0)
    assert estimate_altitude_variance(np.arange(200.0) * 0.0, sample_rate_hz=40.0) == 0.0


def test_refuses_fewer_than_10_samples() -> None:
    with pytest.raises(ValueError, match="at least 10"):
        estimate_altitude_variance(np.zeros(9), sample_rate_hz=40.0)


def test_refuses_non_finite_altitudes() -> None:
    with pytest.raises(ValueError, match="NaN"):
        estimate_altitude_variance([0.0] * 11 + [float("nan")], sample_rate_hz=40.0)
