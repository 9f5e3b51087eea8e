"""Row-by-row conformance with the Freescale build 422 reference on dataset A (first 20 s).

Data (tests/data/filters): ``fsl_imu_A_counts.csv`` is the first 4000 rows (200 Hz) of the
conformance input imu_A as int16 counts (accel 1/2048 g gravity positive, gyro 1/128 deg/s,
mag 1/16 uT, body NED); ``fsl_*_kalman_A_first20s.csv`` are the reference outputs of
fRun_9DOF_GBY_KALMAN / fRun_6DOF_GY_KALMAN (NED build, oversample ratio 8 -> 25 Hz Kalman,
magnetic calibration forced valid with B = 50 uT) for the same rows.

Tolerances: the reference runs in float32 with polynomial trig; a float64 port agrees within
about 3e-4 deg. The stated limits are 0.1 deg on orientation (angle between quaternions)
and on each Euler angle at every Kalman step, 1e-3 deg/s on the gyro offset estimate and
0.01 deg on the tracked inclination; the jamming flag must match exactly.
"""

from __future__ import annotations

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


def _inputs() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    c = np.loadtxt(DATA / "fsl_imu_A_counts.csv", delimiter=",", skiprows=2)
    return c[:, 1:4] / 2048.0, c[:, 4:7] / 128.0, c[:, 7:10] / 16.0


def _reference(name: str) -> np.ndarray:
    return np.genfromtxt(DATA / f"{name}_first20s.csv", delimiter=",", names=True)


def _quat_angle_deg(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Angle of the rotation between rows of two quaternion arrays (sign-insensitive).

    Uses atan2 of the vector and scalar parts of a* b, which stays accurate for tiny angles
    (arccos of the dot product does not: float32 norms alone would read as 0.05 deg).
    """
    a = a / np.linalg.norm(a, axis=1, keepdims=True)
    b = b / np.linalg.norm(b, axis=1, keepdims=True)
    w = np.sum(a * b, axis=1)
    v = (a[:, :1] * b[:, 1:] - b[:, :1] * a[:, 1:] - np.cross(a[:, 1:], b[:, 1:]))
    return np.degrees(2.0 * np.arctan2(np.linalg.norm(v, axis=1), np.abs(w)))


def _wrapped(d: np.ndarray) -> np.ndarray:
    return (d + 180.0) % 360.0 - 180.0


@pytest.fixture(scope="module")
def nine() -> tuple[BatchResult, np.ndarray]:
    acc, gyr, mag = _inputs()
    return run_9dof(acc, gyr, mag, REF9), _reference("fsl_9dof_gby_kalman_A")


@pytest.fixture(scope="module")
def six() -> tuple[BatchResult, np.ndarray]:
    acc, gyr, _ = _inputs()
    return run_6dof(acc, gyr, REF6), _reference("fsl_6dof_gy_kalman_A")


def _ref_quat(ref: np.ndarray) -> np.ndarray:
    return np.c_[ref["q0"], ref["q1"], ref["q2"], ref["q3"]]


@pytest.mark.parametrize("which", ["nine", "six"])
def test_kalman_runs_on_every_eighth_sample_and_the_first_step_only_initialises(
        which: str, request: pytest.FixtureRequest) -> None:
    result, ref = request.getfixturevalue(which)
    np.testing.assert_array_equal(result.row, ref["idx"].astype(int))
    np.testing.assert_array_equal(result.valid, ref["kf_valid"].astype(bool))
    assert not result.valid[0] and result.valid[1:].all()
    np.testing.assert_array_equal(result.q_body_to_ned[0], [1.0, 0.0, 0.0, 0.0])


@pytest.mark.parametrize("which", ["nine", "six"])
def test_orientation_matches_reference_within_0_1_deg_at_every_step(
        which: str, request: pytest.FixtureRequest) -> None:
    result, ref = request.getfixturevalue(which)
    err = _quat_angle_deg(result.q_body_to_ned, _ref_quat(ref))
    assert err.max() < ANGLE_TOL_DEG, f"worst step {int(np.argmax(err))}: {err.max():.4f} deg"


@pytest.mark.parametrize("which", ["nine", "six"])
def test_freescale_euler_angles_match_reference_within_0_1_deg(
        which: str, request: pytest.FixtureRequest) -> None:
    result, ref = request.getfixturevalue(which)
    ours = result.euler_deg[1:]
    theirs = np.c_[ref["roll_deg"], ref["pitch_deg"], ref["yaw_deg"]][1:]
    assert np.all((ours[:, 2] >= 0.0) & (ours[:, 2] < 360.0)), "NED yaw is 0..360"
    assert np.abs(_wrapped(ours - theirs)).max() < ANGLE_TOL_DEG


@pytest.mark.parametrize("which", ["nine", "six"])
def test_gyro_offset_estimate_matches_reference(
        which: str, request: pytest.FixtureRequest) -> None:
    result, ref = request.getfixturevalue(which)
    theirs = np.c_[ref["gbias_x_dps"], ref["gbias_y_dps"], ref["gbias_z_dps"]]
    np.testing.assert_allclose(result.gyro_offset_dps, theirs, atol=1e-3)


def test_inclination_tracking_matches_reference(nine: tuple[BatchResult, np.ndarray]) -> None:
    result, ref = nine
    np.testing.assert_allclose(result.inclination_deg, ref["incl_deg"], atol=0.01)
    # it starts from zero inclination and climbs towards the true 60 deg
    assert result.inclination_deg[-1] == pytest.approx(60.0, abs=2.0)


def test_jamming_flag_matches_reference_exactly(nine: tuple[BatchResult, np.ndarray]) -> None:
    result, ref = nine
    np.testing.assert_array_equal(result.mag_jamming, ref["mag_jam"].astype(bool))


def test_build_422_partial_innovation_inverse_is_what_the_reference_computes() -> None:
    """The textbook full 6x6 inverse is a different filter: it misses the reference."""
    acc, gyr, mag = _inputs()
    ref = _reference("fsl_9dof_gby_kalman_A")
    full = run_9dof(acc, gyr, mag, Freescale9DofSettings(preset="reference",
                                                      full_innovation_inverse=True))
    assert np.abs(full.inclination_deg - ref["incl_deg"]).max() > 1.0


def test_reference_fuses_the_newest_fast_sample_not_the_window_average() -> None:
    acc, gyr, _ = _inputs()
    ref = _reference("fsl_6dof_gy_kalman_A")
    averaged = run_6dof(acc, gyr, Freescale6DofSettings(preset="reference",
                                                          accel_mag_input="average"))
    assert _quat_angle_deg(averaged.q_body_to_ned, _ref_quat(ref)).max() > 0.2
