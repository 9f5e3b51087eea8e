"""The decoupled estimator's ``preset: adaptive`` weights its accelerometer filter by the
innovation speed (imuhal_filters.common.innovation): one setting for a hand-held board and
for an aeroplane, on synthetic motion (on BROAD it is not yet good enough: docs/estimators.md).

Seeded synthetic motions with known truth, no speed source (nothing to compensate a turn
with): a board turned and shaken by hand for a minute with an uncalibrated gyro
(tests/filters/decoupled_motion.py), and an aeroplane at 20 m/s (decoupled_flight_motion.py)
in a coordinated 15 deg/s turn (28 deg of bank) through turbulence, or rolling with a 3 %
gyro scale error and then flying straight through turbulence. Each figure is compared with
the two fixed settings: ``preset: handheld`` (VQF's, every reading in full) and the
defaults, ``preset: flight`` (a 0.02 g gate, 10 s, the turbulence correction).
"""

from __future__ import annotations

import numpy as np
from tests.filters.decoupled_flight_motion import Flight, flight
from tests.filters.decoupled_motion import Motion, hand_motion, tilt_error_deg

from imuhal_filters.decoupled.estimator import DecoupledEstimator

BIAS_RAD_S = (0.01, -0.015, 0.008)


def _tilt_deg(f: Flight | Motion, settings: dict) -> np.ndarray:
    est = DecoupledEstimator({"sample_period_s": f.dt_s, "use_mag": False, "preset": "adaptive",
                              **settings})
    q = [est.update(g, a, None, f.dt_s) for g, a in zip(f.gyro_rad_s, f.accel_m_s2, strict=True)]
    return tilt_error_deg(np.array(q), f.q_true)


def _rms(x: np.ndarray) -> float:
    return float(np.sqrt(np.mean(x**2)))


def test_in_a_turn_without_a_speed_source_adaptive_gates_the_centripetal_acceleration(
        ) -> None:
    f = flight(60.0, turn_deg_s=15.0)
    late = f.t_s >= 20.0
    adaptive = _rms(_tilt_deg(f, {})[late])
    handheld = _rms(_tilt_deg(f, {"preset": "handheld"})[late])
    flight_preset = _rms(_tilt_deg(f, {"preset": "flight"})[late])
    assert handheld > 20.0  # measured 26.9: pulled to the apparent vertical
    assert adaptive < 0.5 * flight_preset  # measured 4.3 against 10.3


def test_a_board_moved_by_hand_keeps_the_correction_the_fixed_gate_starves() -> None:
    m = hand_motion(60.0, BIAS_RAD_S)
    after = np.arange(m.q_true.shape[0]) * m.dt_s >= 5.0
    adaptive = _rms(_tilt_deg(m, {})[after])
    handheld = _rms(_tilt_deg(m, {"preset": "handheld"})[after])
    flight_preset = _rms(_tilt_deg(m, {"preset": "flight"})[after])
    assert flight_preset > 10.0  # measured 20.4: the gate closed, the gyro bias uncorrected
    assert adaptive < 0.2 * flight_preset  # measured 2.9
    assert adaptive < 3.0 * handheld  # measured 2.9 against 1.3: the price of the gating


def test_a_manoeuvres_gyro_error_is_walked_back_in_turbulence_without_the_turbulence_rule() -> None:
    # the axial roll leaves about 10 deg; the gusts are zero-mean, their speed small
    f = flight(30.0)
    tilt = _tilt_deg(f, {})
    assert tilt[(f.t_s > 5.5) & (f.t_s < 6.5)].mean() > 8.0
    assert tilt[f.t_s >= 20.0].max() < 1.0  # measured 0.34
