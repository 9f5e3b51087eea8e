"""BROAD's error metrics against hand-computed cases."""

from __future__ import annotations

import math

import numpy as np
import pytest

from imuhal.evaluate.metrics import (
    error_quaternion_earth,
    heading_error_rad,
    inclination_error_rad,
    rmse_deg,
    total_error_rad,
)


def _axis_angle(axis: tuple[float, float, float], deg: float) -> np.ndarray:
    a = np.asarray(axis, float) / np.linalg.norm(axis)
    h = math.radians(deg) / 2
    return np.r_[math.cos(h), math.sin(h) * a]


def _qmul(p: np.ndarray, q: np.ndarray) -> np.ndarray:
    pw, px, py, pz = p
    qw, qx, qy, qz = q
    return np.array([pw * qw - px * qx - py * qy - pz * qz, pw * qx + px * qw + py * qz - pz * qy,
                     pw * qy - px * qz + py * qw + pz * qx, pw * qz + px * qy - py * qx + pz * qw])


TRUTH = _axis_angle((0.3, -0.5, 0.8), 70.0)


def test_a_perfect_estimate_has_no_error():
    e = rmse_deg(np.tile(TRUTH, (5, 1)), np.tile(TRUTH, (5, 1)))
    assert e.total_deg == pytest.approx(0.0, abs=1e-6)
    assert e.heading_deg == pytest.approx(0.0, abs=1e-6)
    assert e.inclination_deg == pytest.approx(0.0, abs=1e-6)


def test_an_error_about_the_vertical_earth_axis_is_all_heading():
    est = _qmul(_axis_angle((0, 0, 1), 10.0), TRUTH)  # rotated 10 deg about earth z
    e = rmse_deg(est[None], TRUTH[None])
    assert (e.total_deg, e.heading_deg) == (pytest.approx(10.0), pytest.approx(10.0))
    assert e.inclination_deg == pytest.approx(0.0, abs=1e-6)


def test_an_error_about_a_horizontal_earth_axis_is_all_inclination():
    est = _qmul(_axis_angle((1, 1, 0), 4.0), TRUTH)
    e = rmse_deg(est[None], TRUTH[None])
    assert (e.total_deg, e.inclination_deg) == (pytest.approx(4.0), pytest.approx(4.0))
    assert e.heading_deg == pytest.approx(0.0, abs=1e-6)


def test_heading_then_tilt_splits_into_its_parts():
    # tilt 3 deg about earth x after 8 deg about earth z: q_err = q_tilt * q_heading
    q_err = _qmul(_axis_angle((1, 0, 0), 3.0), _axis_angle((0, 0, 1), 8.0))
    est = _qmul(q_err, TRUTH)
    err = error_quaternion_earth(est[None], TRUTH[None])
    assert math.degrees(heading_error_rad(err)[0]) == pytest.approx(8.0)
    assert math.degrees(inclination_error_rad(err)[0]) == pytest.approx(3.0)
    # cos(total/2) = cos(1.5 deg) cos(4 deg): the product of the two half-angle cosines
    expected = 2 * math.degrees(math.acos(math.cos(math.radians(1.5)) * math.cos(math.radians(4))))
    assert math.degrees(total_error_rad(err)[0]) == pytest.approx(expected)


def test_the_sign_of_a_quaternion_does_not_change_the_error():
    est = _qmul(_axis_angle((0, 1, 0), 5.0), TRUTH)
    assert rmse_deg(-est[None], TRUTH[None]).total_deg == pytest.approx(5.0)


def test_rmse_is_the_root_mean_square_over_the_mask():
    errs = [2.0, 4.0, 100.0]
    est = np.array([_qmul(_axis_angle((1, 0, 0), d), TRUTH) for d in errs])
    e = rmse_deg(est, np.tile(TRUTH, (3, 1)), np.array([True, True, False]))
    assert e.total_deg == pytest.approx(math.sqrt((4 + 16) / 2))
    assert e.evaluated == 2


def test_rows_without_an_estimate_are_counted_missing_not_correct():
    est = np.array([_qmul(_axis_angle((1, 0, 0), 3.0), TRUTH), [np.nan] * 4])
    e = rmse_deg(est, np.tile(TRUTH, (2, 1)))
    assert e.total_deg == pytest.approx(3.0)
    assert (e.evaluated, e.missing) == (1, 1)


def test_a_mask_of_the_wrong_length_is_refused():
    with pytest.raises(ValueError, match="mask"):
        rmse_deg(np.tile(TRUTH, (3, 1)), np.tile(TRUTH, (3, 1)), np.ones(2, bool))
