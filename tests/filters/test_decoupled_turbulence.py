"""The decoupled estimator in turbulence: a closed gate no longer keeps a manoeuvre's gyro error.

Seeded synthetic aeroplane flights with known truth (tests/filters/decoupled_flight_motion.py:
an axial roll measured with a 3 % gyro scale error leaves about 10 deg of tilt error, then
turbulence that keeps |a| about 0.3 g from 1 g, so ``preset: flight``'s 0.02 g soft gate
stays closed); ``preset: flight`` is the defaults by name.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
from tests.filters.ahrs_cases import G0
from tests.filters.decoupled_flight_motion import Flight, flight
from tests.filters.decoupled_motion import tilt_error_deg

from imuhal_filters.common.quat import IDENTITY
from imuhal_filters.decoupled.core import ButterworthLowPass, DecoupledKernel, turn_state_towards
from imuhal_filters.decoupled.estimator import DecoupledEstimator
from imuhal_filters.decoupled.turbulence import TurbulenceParams


def _estimator_tilt_deg(f: Flight, settings: dict) -> np.ndarray:
    est = DecoupledEstimator({"sample_period_s": f.dt_s, "preset": "flight", **settings})
    q = [est.update(g, a, None, f.dt_s) for g, a in zip(f.gyro_rad_s, f.accel_m_s2, strict=True)]
    return tilt_error_deg(np.array(q), f.q_true)


def _kernel_run(f: Flight, turbulence: TurbulenceParams) -> tuple[np.ndarray, np.ndarray]:
    """(tilt error deg, straight flight declared) per sample, ``preset: flight`` otherwise."""
    params = dataclasses.replace(DecoupledEstimator({"preset": "flight"}).settings.params(),
                                 turbulence=turbulence)
    k = DecoupledKernel(params)
    k.start(IDENTITY)  # the flights start level, heading north
    q, steady = [], []
    for g, a in zip(f.gyro_rad_s.tolist(), (-f.accel_m_s2 / G0).tolist(), strict=True):
        q.append(k.step(g, a, None, f.dt_s))
        steady.append(k.straight.steady)
    return tilt_error_deg(np.array(q), f.q_true), np.array(steady)


def test_in_straight_flight_through_turbulence_a_rolls_gyro_error_is_walked_back() -> None:
    f = flight(30.0)
    late = f.t_s >= 20.0
    tilt = _estimator_tilt_deg(f, {})
    assert tilt[(f.t_s > 5.5) & (f.t_s < 6.5)].mean() > 8.0  # the roll's error is there
    assert tilt[late].max() < 1.0  # measured 0.5
    kept = _estimator_tilt_deg(f, {"turbulence_rate_deg_s": None})
    assert kept[late].min() > 8.0  # without the correction the closed gate keeps it


def test_the_correction_is_capped_at_its_rate() -> None:
    f = flight(12.0)
    tilt = _estimator_tilt_deg(f, {"turbulence_rate_deg_s": 1.0})
    after_roll = tilt[(f.t_s > 5.5) & (f.t_s < 6.5)].mean()
    corrected = after_roll - tilt[-1]
    # the turbulence starts at 6 s: by 12 s at most 1 deg/s * 6 s can have been corrected
    assert 1.0 < corrected < 6.0  # measured 2.2 (the gate's closed share, once detected)


def test_a_steady_turn_through_turbulence_is_not_taken_for_straight_flight() -> None:
    # 6 deg/s at 20 m/s: 12 deg of coordinated bank, |a| only 1.02 g: the gyro's vertical
    # turn rate, not |a|, tells the turn from straight flight
    f = flight(30.0, turn_deg_s=6.0, roll_360=False)
    turning = f.t_s >= 10.0
    tilt, steady = _kernel_run(f, TurbulenceParams())
    assert not steady[turning].any()
    assert tilt[turning].max() < 1.5  # measured 0.7
    unguarded, steady = _kernel_run(f, TurbulenceParams(turn_max_rad_s=math.inf))
    assert steady[turning].mean() > 0.5
    assert unguarded[f.t_s >= 25.0].mean() > 5.0  # pulled towards the apparent vertical


def test_turning_a_filter_state_moves_value_and_rate_by_at_most_the_cap() -> None:
    filt = ButterworthLowPass(3.0)
    filt.state = [0.0, 0.0, 1.0, 0.0, 0.2, 0.0]
    out = turn_state_towards(filt, (1.0, 0.0, 0.0), 0.01)
    assert math.isclose(math.atan2(out[0], out[2]), 0.01, rel_tol=1e-9)
    assert filt.state is not None
    np.testing.assert_allclose(filt.state[3:], [0.0, 0.2, 0.0], atol=1e-12)  # y is the axis
    out = turn_state_towards(filt, (1.0, 0.0, 1.0), 1.0)  # within the cap: reaches it
    assert math.isclose(math.atan2(out[0], out[2]), math.pi / 4, rel_tol=1e-9)
    assert math.isclose(math.hypot(out[0], out[2]), 1.0, rel_tol=1e-12)


def test_preset_flight_corrects_in_turbulence_and_the_defaults_and_handheld_do_not() -> None:
    # the defaults have no gate for turbulence to keep closed: the manoeuvre detector lets
    # gusts through (common/innovation.py), so the filter averages them out itself
    assert DecoupledEstimator().settings.turbulence_rate_deg_s is None
    assert DecoupledEstimator({"preset": "flight"}).settings.turbulence_rate_deg_s == 3.0
    assert DecoupledEstimator({"preset": "handheld"}).settings.turbulence_rate_deg_s is None
