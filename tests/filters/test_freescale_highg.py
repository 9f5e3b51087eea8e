"""High-g behaviour of the Freescale filters: the loop of ``rc-flight``, step by step against
the public reference (fusion.c build 422, NED build).

Data (tests/data/filters; each file's header says how, and docs/scripts/fsl_highg rebuilds
all four byte for byte: make_inputs.py for the inputs, harness.c with the public library for
the reference outputs):
``fsl_highg_counts.csv`` is 560 fast samples (200 Hz, t = 15.600-18.395 s) of imuhal's
``rc-flight`` scenario, seed 1, with the conformance field (50 uT, 60 deg inclination) and
ideal sensors, as int16 counts (accel 1/2048 g gravity positive, gyro 1/128 deg/s, mag 1/16
uT, body NED): 0.4 s of cruise, then the first 2.4 s of the loop (up to about 5 g).
``fsl_highg_{9dof_gby,6dof_gy}_kalman.csv`` are the reference's outputs for those samples,
with the filter reset at the first one; ``fsl_highg_truth.csv`` is the true attitude at the
Kalman rows.

The reference itself loses the attitude in the loop: it has no accelerometer gate, so it
reads the centripetal load as gravity, holds the attitude near level and winds its gyro offset
estimate up to cancel the pitch rate. A faithful port must do the same.

Tolerances: 0.1 deg on orientation (angle between quaternions) at every Kalman step (the port
agrees within about 1e-4 deg here), 0.01 deg/s on the gyro offset estimate, 0.01 deg on the
tracked inclination; the jamming flag must match exactly.
"""

from __future__ import annotations

import io
from pathlib import Path

import numpy as np
import pytest

from imuhal_filters.freescale.batch import BatchResult, run_6dof, run_9dof
from imuhal_filters.freescale.settings import Freescale6DofSettings, Freescale9DofSettings

REF9 = Freescale9DofSettings(preset="reference")
REF6 = Freescale6DofSettings(preset="reference")
"""Build 422 as published: what the reference outputs were made with."""

DATA = Path(__file__).parent.parent / "data" / "filters"
ANGLE_TOL_DEG = 0.1
OFFSET_TOL_DPS = 0.01
LOOP_START_S = 16.0


def _read(name: str) -> np.ndarray:
    """A CSV with ``#`` comment lines before its header row, as a structured array."""
    text = "".join(line for line in (DATA / name).read_text().splitlines(keepends=True)
                   if not line.startswith("#"))
    return np.genfromtxt(io.StringIO(text), delimiter=",", names=True)


def _inputs() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    c = _read("fsl_highg_counts.csv")
    acc = np.c_[c["ax"], c["ay"], c["az"]] / 2048.0
    gyr = np.c_[c["gx"], c["gy"], c["gz"]] / 128.0
    mag = np.c_[c["mx"], c["my"], c["mz"]] / 16.0
    return acc, gyr, mag


def _quat_angle_deg(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Angle of the rotation between rows of two quaternion arrays (sign-insensitive; atan2
    form, accurate for tiny angles where arccos of float32 dot products is not)."""
    a = a / np.linalg.norm(a, axis=1, keepdims=True)
    b = b / np.linalg.norm(b, axis=1, keepdims=True)
    w = np.sum(a * b, axis=1)
    v = a[:, :1] * b[:, 1:] - b[:, :1] * a[:, 1:] - np.cross(a[:, 1:], b[:, 1:])
    return np.degrees(2.0 * np.arctan2(np.linalg.norm(v, axis=1), np.abs(w)))


def _tilt_error_deg(q_est: np.ndarray, q_true: np.ndarray) -> np.ndarray:
    """Angle between the estimated and true gravity (NED down) directions in the body."""
    def down_in_body(q: np.ndarray) -> np.ndarray:
        w, x, y, z = (q / np.linalg.norm(q, axis=1, keepdims=True)).T
        return np.c_[2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]
    cos = np.sum(down_in_body(q_est) * down_in_body(q_true), axis=1)
    return np.degrees(np.arccos(np.clip(cos, -1.0, 1.0)))


def _quat(ref: np.ndarray) -> np.ndarray:
    return np.c_[ref["q0"], ref["q1"], ref["q2"], ref["q3"]]


@pytest.fixture(scope="module")
def nine() -> tuple[BatchResult, np.ndarray]:
    acc, gyr, mag = _inputs()
    return run_9dof(acc, gyr, mag, REF9), _read("fsl_highg_9dof_gby_kalman.csv")


@pytest.fixture(scope="module")
def six() -> tuple[BatchResult, np.ndarray]:
    acc, gyr, _ = _inputs()
    return run_6dof(acc, gyr, REF6), _read("fsl_highg_6dof_gy_kalman.csv")


@pytest.fixture(scope="module")
def truth() -> np.ndarray:
    return _read("fsl_highg_truth.csv")


@pytest.mark.parametrize("which", ["nine", "six"])
def test_steps_line_up_with_the_reference(which: str, request: pytest.FixtureRequest) -> None:
    result, ref = request.getfixturevalue(which)
    np.testing.assert_array_equal(result.row, ref["idx"].astype(int))
    np.testing.assert_array_equal(result.valid, ref["kf_valid"].astype(bool))


@pytest.mark.parametrize("which", ["nine", "six"])
def test_orientation_follows_the_reference_through_the_loop_within_0_1_deg(
        which: str, request: pytest.FixtureRequest) -> None:
    result, ref = request.getfixturevalue(which)
    err = _quat_angle_deg(result.q_body_to_ned, _quat(ref))
    worst = int(np.argmax(err))
    assert err.max() < ANGLE_TOL_DEG, (
        f"step {worst} (t = {ref['t_s'][worst]:.3f} s): {err.max():.4f} deg off the reference")


@pytest.mark.parametrize("which", ["nine", "six"])
def test_gyro_offset_wind_up_matches_the_reference(
        which: str, request: pytest.FixtureRequest) -> None:
    result, ref = request.getfixturevalue(which)
    theirs = np.c_[ref["gbias_x_dps"], ref["gbias_y_dps"], ref["gbias_z_dps"]]
    # the loop drives the pitch-axis offset estimate far from the true zero
    assert np.abs(theirs[:, 1]).max() > 50.0
    np.testing.assert_allclose(result.gyro_offset_dps, theirs, atol=OFFSET_TOL_DPS)


def test_inclination_and_jamming_follow_the_reference(
        nine: tuple[BatchResult, np.ndarray]) -> None:
    result, ref = nine
    # the loop swings the tracked inclination between both +-65 deg limits
    assert ref["incl_deg"].min() == pytest.approx(-65.0) and ref["incl_deg"].max() == 65.0
    np.testing.assert_allclose(result.inclination_deg, ref["incl_deg"], atol=0.01)
    np.testing.assert_array_equal(result.mag_jamming, ref["mag_jam"].astype(bool))


@pytest.mark.parametrize("which", ["nine", "six"])
def test_the_port_loses_the_attitude_in_the_loop_as_the_reference_does(
        which: str, request: pytest.FixtureRequest, truth: np.ndarray) -> None:
    """Near level in cruise (< 3 deg), more than 150 deg of tilt error 2.4 s into the loop."""
    result, ref = request.getfixturevalue(which)
    np.testing.assert_array_equal(truth["idx"], ref["idx"])
    valid = result.valid
    q_true = np.c_[truth["qw"], truth["qx"], truth["qy"], truth["qz"]][valid]
    ours = _tilt_error_deg(result.q_body_to_ned[valid], q_true)
    cruise = truth["t_s"][valid] < LOOP_START_S
    assert ours[cruise].max() < 3.0
    assert ours.max() > 150.0
