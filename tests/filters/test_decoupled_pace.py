"""The decoupled estimator's pace (imuhal_filters/decoupled/pace.py): the accelerometer
filter runs faster while the board rotates fast with little acceleration (the strapdown's
error, a share of the rotation, dominates), and at its own time constant otherwise.

The statistic is fed directly (200 Hz); the estimator, a board tumbling about its x axis
with a 3 % gyro scale error (its accelerometer at the centre of rotation: gravity alone),
and a level board moved by hand without turning (seeded noise).
"""

from __future__ import annotations

import math

import numpy as np

from imuhal_filters.common.quat import tilt_error_deg
from imuhal_filters.decoupled.estimator import DecoupledEstimator
from imuhal_filters.decoupled.pace import RotationPace

DT_S = 0.005
G = 9.80665
TAU_S = 3.0
EPS = 0.03
LEVEL = (0.0, 0.0, 1.0)


def _settle(pace: RotationPace, rate_rad_s: float, innovation_m_s2: float,
            seconds: float = 20.0) -> float:
    """Feed a rotation about x and an innovation along x (alternating in sign, as a hand's
    strokes) for ``seconds``; returns the last factor."""
    factor = 1.0
    for i in range(round(seconds / DT_S)):
        sign = 1.0 if (i // 100) % 2 == 0 else -1.0
        reading = (sign * innovation_m_s2 / G, 0.0, 1.0)
        factor = pace.step(reading, LEVEL, (rate_rad_s, 0.0, 0.0), DT_S)
    return factor


def test_a_still_board_keeps_the_filters_own_time_constant() -> None:
    assert _settle(RotationPace(TAU_S, EPS), 0.0, 0.0) == 1.0


def test_a_fast_rotation_without_acceleration_runs_the_filter_faster() -> None:
    rate = math.radians(360.0)
    factor = _settle(RotationPace(TAU_S, EPS), rate, 0.0)
    # the innovation is under the floor (1 m/s^2): tau = floor / (g eps omega)
    assert math.isclose(factor, G * EPS * rate * TAU_S / 1.0, rel_tol=1e-3)


def test_the_same_rotation_with_a_hands_acceleration_runs_slower() -> None:
    rate = math.radians(360.0)
    calm = _settle(RotationPace(TAU_S, EPS), rate, 0.0)
    shaken = _settle(RotationPace(TAU_S, EPS), rate, 4.0)
    assert 1.0 <= shaken < calm
    assert math.isclose(shaken, max(1.0, G * EPS * rate * TAU_S / 4.0), rel_tol=1e-2)


def test_acceleration_along_gravity_does_not_slow_it() -> None:
    rate = math.radians(360.0)
    calm = _settle(RotationPace(TAU_S, EPS), rate, 0.0)
    pace = RotationPace(TAU_S, EPS)
    factor = 1.0
    for i in range(round(20.0 / DT_S)):
        sign = 1.0 if (i // 100) % 2 == 0 else -1.0
        factor = pace.step((0.0, 0.0, 1.0 + sign * 4.0 / G), LEVEL, (rate, 0.0, 0.0), DT_S)
    assert math.isclose(factor, calm, rel_tol=1e-9)


def _tumbling(seconds: float, rate_dps: float, seed: int = 3
              ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A board tumbling about its x axis at ``rate_dps``, its gyro reading 3 % high: gyro
    and accelerometer rows (body NED, rad/s, m/s^2, white noise) and the true attitudes."""
    rng = np.random.default_rng(seed)
    t = np.arange(round(seconds / DT_S)) * DT_S
    roll = math.radians(rate_dps) * t
    q = np.stack([np.cos(roll / 2), np.sin(roll / 2), 0 * t, 0 * t], axis=1)
    # gravity (NED down) seen in the body rolled by phi: (0, g sin phi, g cos phi); the
    # specific force is its negative
    acc = np.stack([0 * t, -G * np.sin(roll), -G * np.cos(roll)], axis=1)
    acc += rng.normal(0.0, 0.05, acc.shape)
    gyro = np.stack([np.full_like(t, math.radians(rate_dps) * (1.0 + EPS)), 0 * t, 0 * t],
                    axis=1) + rng.normal(0.0, 0.002, acc.shape)
    return gyro, acc, q


def _tilt_rms_deg(settings: dict[str, object], gyro: np.ndarray, acc: np.ndarray,
                  truth: np.ndarray, from_s: float = 5.0) -> float:
    est = DecoupledEstimator({"sample_period_s": DT_S, "use_mag": False, **settings})
    errors = []
    for i, (g, a) in enumerate(zip(gyro, acc, strict=True)):
        q = est.update(g, a, None, DT_S)
        if i * DT_S >= from_s and q is not None:
            errors.append(tilt_error_deg(tuple(q), tuple(truth[i])))
    return float(np.sqrt(np.mean(np.square(errors))))


def test_a_tumbling_board_with_a_gyro_scale_error_keeps_a_smaller_tilt_error() -> None:
    # VQF's settings (no manoeuvre detector) with and without the pace
    gyro, acc, truth = _tumbling(30.0, 180.0)
    paced = _tilt_rms_deg({"preset": "handheld", "gyro_relative_error": EPS}, gyro, acc, truth)
    fixed = _tilt_rms_deg({"preset": "handheld"}, gyro, acc, truth)
    assert paced < 0.5 * fixed


def test_the_defaults_keep_a_tumbling_board_within_a_few_degrees() -> None:
    # without the pace the strapdown's drift (9 deg/s) is a steady innovation, which the
    # manoeuvre detector withholds as a vehicle's push: the tilt is lost (about 100 deg)
    gyro, acc, truth = _tumbling(30.0, 180.0)
    assert _tilt_rms_deg({}, gyro, acc, truth) < 5.0


def test_hand_motion_without_rotation_is_filtered_exactly_as_without_the_pace() -> None:
    # a level board moved back and forth 0.3 m at 1 Hz with the hand's scatter: the rotation
    # is the gyro's noise, so the filter keeps its own time constant, sample for sample
    rng = np.random.default_rng(5)
    t = np.arange(round(20.0 / DT_S)) * DT_S
    x = 0.3 * (2 * math.pi) ** 2 * np.sin(2 * math.pi * t)
    acc = np.stack([x, 0.5 * x, np.full_like(t, -G)], axis=1) + rng.normal(0.0, 1.0, (t.size, 3))
    gyro = rng.normal(0.0, 0.002, acc.shape)

    def attitudes(settings: dict[str, object]) -> np.ndarray:
        est = DecoupledEstimator({"sample_period_s": DT_S, "use_mag": False, **settings})
        return np.array([est.update(g, a, None, DT_S) for g, a in zip(gyro, acc, strict=True)])

    assert np.array_equal(attitudes({}), attitudes({"gyro_relative_error": None}))


def test_state_round_trips_with_the_pace_and_continues_identically() -> None:
    gyro, acc, _ = _tumbling(6.0, 180.0)
    a = DecoupledEstimator({"sample_period_s": DT_S, "use_mag": False})
    n = len(gyro) // 2
    for g, f in zip(gyro[:n], acc[:n], strict=True):
        a.update(g, f, None, DT_S)
    assert a.get_state()["filter"]["pace"][1] > 0.0
    b = DecoupledEstimator({"sample_period_s": DT_S, "use_mag": False})
    b.set_state(a.get_state())
    qa = [a.update(g, f, None, DT_S) for g, f in zip(gyro[n:], acc[n:], strict=True)]
    qb = [b.update(g, f, None, DT_S) for g, f in zip(gyro[n:], acc[n:], strict=True)]
    assert np.array_equal(qa, qb)
