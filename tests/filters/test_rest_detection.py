"""Rest detection in the complementary AHRS (madgwick, mahony, imufilter; common/rest.py).
The Freescale Kalman filters' use of the same detector: tests/filters/test_freescale_rest.py.

A board lying still is detected after ``rest_min_s`` (1.5 s); there its accelerometer is
trusted fully (soft-gate weight 1) and its gyro bias is learned and subtracted from then on.
Synthetic 200 Hz streams, seeded noise of the bundled chips' order (gyro 0.1 deg/s, accel
3 mg RMS). Blocks against frames one by one, and the compiled steps against Python, with
the rest detector's state: tests/filters/test_ahrs_blocks.py, test_compiled_sample.py.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest

from imuhal.core.frames import quat_from_euler_deg
from imuhal.core.samples import AccelSample, Frame, GyroSample
from imuhal.estimation.outputs import AttitudeEstimate
from imuhal_filters.common.ahrs import AhrsEstimator
from imuhal_filters.common.quat import tilt_error_deg
from imuhal_filters.imufilter.estimator import ImuFilterEstimator
from imuhal_filters.madgwick.estimator import MadgwickEstimator
from imuhal_filters.mahony.estimator import MahonyEstimator

G0 = 9.80665
DT_NS = 5_000_000
BIAS_DEG_S = (1.0, -0.8, 0.6)
"""A gyro turn-on offset like the emulated MAX21100's (about 1 deg/s per axis)."""


def _feed(est: AhrsEstimator, seconds: float, *, roll_deg: float = 0.0,
          rate_deg_s: tuple[float, float, float] = (0.0, 0.0, 0.0),
          accel_until_s: float | None = None, seed: int = 1, t0_s: float = 0.0
          ) -> list[AttitudeEstimate]:
    """A board held at ``roll_deg`` (its accelerometer reads gravity there), its gyro
    reading ``rate_deg_s`` plus BIAS_DEG_S and noise; the accelerometer stops after
    ``accel_until_s``."""
    rng = np.random.default_rng(seed)
    q = quat_from_euler_deg(roll_deg, 0.0, 0.0)
    w, x, y, z = q
    # gravity-positive reading R(q)^T (0, 0, 1) as specific force (m/s^2)
    down = (2 * (x * z - w * y), 2 * (y * z + w * x), w * w - x * x - y * y + z * z)
    out: list[AttitudeEstimate] = []
    for i in range(round(seconds * 1e9 / DT_NS)):
        t = round(t0_s * 1e9) + i * DT_NS
        if accel_until_s is None or t < accel_until_s * 1e9:
            a = [-G0 * d + G0 * 0.003 * n for d, n in zip(down, rng.normal(size=3),
                                                           strict=True)]
            est.process(AccelSample(t_ns=t, device="imu", frame=Frame.BODY_NED,
                                    accel_m_s2=(a[0], a[1], a[2])))
        g = [math.radians(r + b + 0.1 * n) for r, b, n in
             zip(rate_deg_s, BIAS_DEG_S, rng.normal(size=3), strict=True)]
        out += [e for e in est.process(GyroSample(t_ns=t, device="imu", frame=Frame.BODY_NED,
                                                  gyro_rad_s=(g[0], g[1], g[2])))
                if isinstance(e, AttitudeEstimate)]
    return out


def _six_dof(cls: type[AhrsEstimator], **settings: Any) -> AhrsEstimator:
    if cls.uses_mag:
        settings["use_mag"] = False
    return cls(cls.Settings(sample_period_s=0.005, **settings))


WITH_REST = [MadgwickEstimator, MahonyEstimator, ImuFilterEstimator]
LEVEL = (1.0, 0.0, 0.0, 0.0)


@pytest.mark.parametrize("cls", WITH_REST)
def test_a_still_board_is_at_rest_once_still_for_the_rest_time(cls: type) -> None:
    out = _feed(_six_dof(cls), 3.0)
    first = next(e.t_ns for e in out if e.diagnostics["at_rest"])
    assert 1.5e9 <= first <= 1.6e9
    assert all(e.diagnostics["at_rest"] for e in out if e.t_ns >= first)
    assert cls is not None and _six_dof(cls).diagnostics()["rest"]["detection"]


@pytest.mark.parametrize("cls", WITH_REST)
def test_the_gyro_bias_is_learned_at_rest(cls: type) -> None:
    est = _six_dof(cls)
    out = _feed(est, 6.0)
    learned = np.degrees(out[-1].diagnostics["rest_gyro_bias_rad_s"])
    assert learned == pytest.approx(BIAS_DEG_S, abs=0.03)
    assert est.diagnostics()["rest"]["gyro_bias_rad_s"] == out[-1].diagnostics[
        "rest_gyro_bias_rad_s"]


@pytest.mark.parametrize("cls", [MadgwickEstimator, MahonyEstimator])
def test_at_rest_the_accelerometer_is_trusted_fully(cls: type) -> None:
    out = _feed(_six_dof(cls), 3.0)
    assert all(e.diagnostics["accel_weight"] == 1.0 for e in out if e.diagnostics["at_rest"])
    assert any(e.diagnostics["accel_weight"] < 1.0 for e in out
               if not e.diagnostics["at_rest"])


def test_at_rest_imufilter_corrects_at_full_gain() -> None:
    """imuFilter's band gain (below 1 once its variance has grown) is 1 at rest."""
    out = _feed(_six_dof(ImuFilterEstimator), 3.0)
    assert all(e.diagnostics["accel_gain"] == 1.0 for e in out if e.diagnostics["at_rest"])
    assert any(e.diagnostics["accel_gain"] < 1.0 for e in out
               if not e.diagnostics["at_rest"])


def test_mahony_holds_a_still_board_against_an_uncorrected_gyro_bias() -> None:
    """The regression rest detection mends: the soft gate fades Mahony's correction as the
    bias drifts the attitude away (peak correction about Kp x width / 2, less than the
    bias), so without rest detection a still board's tilt runs away."""
    with_rest = _feed(_six_dof(MahonyEstimator), 30.0)
    without = _feed(_six_dof(MahonyEstimator, rest_detection=False), 30.0)
    # before the rest time (1.5 s) the bias drifts it about a degree; then it is taken back
    assert max(tilt_error_deg(e.q_body_to_ned, LEVEL) for e in with_rest) < 2.0
    assert max(tilt_error_deg(e.q_body_to_ned, LEVEL) for e in with_rest
               if e.t_ns >= 10e9) < 0.3
    assert tilt_error_deg(without[-1].q_body_to_ned, LEVEL) > 5.0


def test_imufilter_starts_up_without_stored_gyro_offsets() -> None:
    """The library has no bias estimate: its correction (``gain`` 0.5 /s) holds a still
    board tilted by the horizontal bias over the gain (1.28 deg/s here: 2.6 deg), for good.
    With rest detection the bias is learned from 1.5 s and the tilt decays with the gain."""
    with_rest = _feed(_six_dof(ImuFilterEstimator), 20.0)
    without = _feed(_six_dof(ImuFilterEstimator, rest_detection=False), 20.0)
    assert max(tilt_error_deg(e.q_body_to_ned, LEVEL) for e in with_rest
               if e.t_ns >= 10e9) < 0.1
    assert min(tilt_error_deg(e.q_body_to_ned, LEVEL) for e in without
               if e.t_ns >= 10e9) > 2.0


def test_imufilter_learns_a_gyro_offset_near_the_mpu9250_tolerance() -> None:
    """A 4, -3, 2 deg/s turn-on offset (inside the MPU-9250's +-5 deg/s): without rest
    detection the still board tumbles (the correction cannot hold 5 deg/s); with it the
    board is at rest at 1.5 s, before the tilt error leaves the accelerometer's reach."""
    more = (3.0, -2.2, 1.4)  # the still gyro's reading on top of BIAS_DEG_S: 4, -3, 2 deg/s
    with_rest = _feed(_six_dof(ImuFilterEstimator), 20.0, rate_deg_s=more)
    without = _feed(_six_dof(ImuFilterEstimator, rest_detection=False), 20.0, rate_deg_s=more)
    assert max(tilt_error_deg(e.q_body_to_ned, LEVEL) for e in with_rest
               if e.t_ns >= 10e9) < 0.2
    assert tilt_error_deg(without[-1].q_body_to_ned, LEVEL) > 10.0


@pytest.mark.parametrize("cls", WITH_REST)
def test_an_upside_down_still_board_converges_as_a_level_one(cls: type) -> None:
    out = _feed(_six_dof(cls), 10.0, roll_deg=180.0)
    upside = quat_from_euler_deg(180.0, 0.0, 0.0)
    assert max(tilt_error_deg(e.q_body_to_ned, upside) for e in out
               if e.t_ns >= 5e9) < 0.3


@pytest.mark.parametrize("cls", WITH_REST)
def test_a_steady_turn_is_not_rest(cls: type) -> None:
    """A rate beyond the first rest's bound (5 deg/s) is motion, however steady."""
    est = _six_dof(cls)
    out = _feed(est, 5.0, rate_deg_s=(0.0, 0.0, 8.0))
    assert not any(e.diagnostics["at_rest"] for e in out)
    assert est.rest_gyro_bias_rad_s == (0.0, 0.0, 0.0)


def test_after_the_bias_is_learned_a_slow_turn_is_not_rest() -> None:
    """Once a bias is known, a rate more than 1 deg/s from it is a turn, not a drift."""
    est = _six_dof(MadgwickEstimator)
    _feed(est, 4.0)
    learned = est.rest_gyro_bias_rad_s
    out = _feed(est, 4.0, rate_deg_s=(0.0, 0.0, 2.0), t0_s=4.0, seed=2)
    assert not any(e.diagnostics["at_rest"] for e in out[-400:])
    assert est.rest_gyro_bias_rad_s == pytest.approx(learned, abs=math.radians(0.05))


def test_without_an_accelerometer_reading_the_board_is_not_at_rest() -> None:
    est = _six_dof(MadgwickEstimator)
    out = _feed(est, 5.0, accel_until_s=3.0)
    assert out[0].t_ns < 3e9 and any(e.diagnostics["at_rest"] for e in out if e.t_ns < 3e9)
    # the held reading goes stale after max_aux_age_s (0.1 s): no reading, no rest
    assert not any(e.diagnostics["at_rest"] for e in out if e.t_ns > 3.2e9)


def test_the_rest_detector_is_saved_and_restored_with_the_state() -> None:
    est = _six_dof(MahonyEstimator)
    _feed(est, 2.0)
    copy = _six_dof(MahonyEstimator)
    copy.set_state(est.get_state())
    a = _feed(est, 2.0, t0_s=2.0, seed=3)
    b = _feed(copy, 2.0, t0_s=2.0, seed=3)
    assert [e.q_body_to_ned for e in a] == [e.q_body_to_ned for e in b]
    assert est.get_state()["rest"] == copy.get_state()["rest"]


@pytest.mark.parametrize("cls", WITH_REST)
@pytest.mark.parametrize("preset", ["reference", "seed"])
def test_the_reference_presets_have_no_rest_detection(cls: type, preset: str) -> None:
    six_dof = {"use_mag": False} if cls.uses_mag else {}
    est = cls(cls.Settings(preset=preset, initial_attitude="first_sample", **six_dof))
    out = _feed(est, 3.0)
    assert not any(e.diagnostics["at_rest"] for e in out)
    assert est.rest_gyro_bias_rad_s == (0.0, 0.0, 0.0)


def test_a_rest_threshold_must_be_positive() -> None:
    with pytest.raises(ValueError, match="rest_min_s"):
        MadgwickEstimator.Settings(rest_min_s=0.0)
