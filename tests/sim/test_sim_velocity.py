"""The simulated GNSS velocity source reports the scenario's velocity late, noisy, at its rate."""

from __future__ import annotations

import numpy as np
import pytest

from imuhal.sim.thermal import ThermalScenario
from imuhal.sim.velocity import GnssVelocityModel, gnss_velocity_samples


def test_samples_are_stamped_at_their_epoch_and_arrive_one_latency_later() -> None:
    pairs = gnss_velocity_samples(ThermalScenario(seed=1), 2.0, GnssVelocityModel(latency_s=0.1))
    assert [s.t_ns for _, s in pairs] == [i * 200_000_000 for i in range(10)]
    assert all(arrival - s.t_ns == 100_000_000 for arrival, s in pairs)
    assert all(s.accuracy_m_s == 0.1 for _, s in pairs)


def test_noise_is_the_models_around_the_true_velocity() -> None:
    scenario = ThermalScenario(seed=1)
    pairs = gnss_velocity_samples(scenario, 60.0, GnssVelocityModel(noise_m_s=0.1), seed=4)
    err = np.array([np.subtract(s.velocity_ned_m_s, scenario.truth(s.t_ns / 1e9)
                                .velocity_ned_m_s) for _, s in pairs])
    assert err.std() == pytest.approx(0.1, rel=0.15)
    assert abs(err.mean()) < 0.02


def test_an_impossible_model_is_refused() -> None:
    with pytest.raises(ValueError, match="rate > 0"):
        GnssVelocityModel(rate_hz=0.0)
