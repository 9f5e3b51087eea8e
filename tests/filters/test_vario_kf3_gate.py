"""vario-kf3's altitude innovation gate (issue 9 item 7).

One wrong but in-range pressure sample used to drive the climb rate to 50-620 m/s. It must
be rejected and counted; a sustained change of level must be re-acquired.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

from imuhal.core.atmosphere import pressure_pa_at_altitude
from imuhal.core.samples import PressureSample
from imuhal.estimation.outputs import AttitudeEstimate, VerticalEstimate
from imuhal_filters.vario.kf3_estimator import VarioKf3Estimator

IMU_NS, BARO_EVERY = 4_000_000, 5  # 250 Hz accelerometer, 50 Hz barometer


def _at_rest(seconds: float, altitude_m: Any, seed: int = 1) -> list[Any]:
    """A vario at rest: 0.12 m barometer noise, 0.02 m/s^2 vertical acceleration noise.
    ``altitude_m(t_s)`` gives what the barometer reads (the truth is 500 m throughout)."""
    rng = np.random.default_rng(seed)
    items: list[Any] = []
    for i in range(1, round(seconds * 250) + 1):
        t = i * IMU_NS
        items.append(AttitudeEstimate(t_ns=t, source="ahrs", q_body_to_ned=(1.0, 0, 0, 0),
                                      linear_accel_ned_m_s2=(0, 0, rng.normal(0, 0.02))))
        if i % BARO_EVERY == 0:
            z = altitude_m(t / 1e9) + rng.normal(0, 0.12)
            items.append(PressureSample(t_ns=t, device="baro",
                                        pressure_pa=pressure_pa_at_altitude(z)))
    return items


def _run(est: VarioKf3Estimator, items: list[Any]) -> list[VerticalEstimate]:
    return [e for item in items for e in est.process(item)]


def _one_wild(t_s: float) -> float:
    # 70 m high for one sample: -830 Pa, well inside the MS5611's range
    return 570.0 if abs(t_s - 5.0) < 0.001 else 500.0


def test_one_wild_pressure_sample_is_rejected_and_counted() -> None:
    # a vario known to start at rest (1 cm/s): every estimate speaks and carries the flag
    est = VarioKf3Estimator({"initial_climb_sigma_m_s": 0.01})
    out = _run(est, _at_rest(8.0, _one_wild))
    assert max(abs(e.climb_m_s) for e in out if e.t_ns > 2e9) < 0.3
    assert est.diagnostics()["gated"] == 1
    assert [e.diagnostics["altitude_gated"] for e in out].count(True) == 1


def test_without_the_gate_the_same_sample_throws_the_climb_rate() -> None:
    est = VarioKf3Estimator({"preset": "reference"})
    out = _run(est, _at_rest(8.0, _one_wild))
    assert max(abs(e.climb_m_s) for e in out) > 10.0


def test_a_sustained_change_of_level_is_reacquired() -> None:
    est = VarioKf3Estimator()
    out = _run(est, _at_rest(8.0, lambda t: 520.0 if t >= 5.0 else 500.0))
    assert est.diagnostics()["reacquired"] == 1
    after = [e for e in out if e.t_ns >= 5.6e9]
    assert all(abs(e.altitude_m - 520.0) < 0.5 for e in after)
    assert all(abs(e.climb_m_s) < 0.5 for e in after)


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_ordinary_noise_never_closes_the_gate(seed: int) -> None:
    est = VarioKf3Estimator()
    _run(est, _at_rest(20.0, lambda t: 500.0, seed=seed))
    assert est.diagnostics()["gated"] == 0
