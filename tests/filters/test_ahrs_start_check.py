"""An AHRS told the board moved at switch-on (``Estimator.moving_at_start``) hands out only
what the accelerometer confirmed (issue 26; docs/estimators.md, "Started in motion").

Plain samples at 200 Hz, body NED: a still, level board (the accelerometer reads -1 g along
z) and the same board turning about its z axis faster than a reading can tell in
(START_CHECK_RATE_RAD_S).
"""

from __future__ import annotations

import math
from collections.abc import Iterator

from imuhal.core.samples import AccelSample, Frame, GyroSample, Sample
from imuhal.estimation.outputs import AttitudeEstimate, EstimateFlag, RejectedEstimate
from imuhal_filters.madgwick.estimator import MadgwickEstimator

PERIOD_NS = 5_000_000
G = 9.80665


def _board(t0_s: float, seconds: float, rate_z_rad_s: float) -> Iterator[Sample]:
    """A level board (specific force straight up) turning at ``rate_z_rad_s`` about z."""
    t0 = round(t0_s * 1e9)
    for i in range(round(seconds * 1e9 / PERIOD_NS)):
        t = t0 + i * PERIOD_NS
        yield AccelSample(t_ns=t, device="imu", frame=Frame.BODY_NED, accel_m_s2=(0.0, 0.0, -G))
        yield GyroSample(t_ns=t, device="imu", frame=Frame.BODY_NED,
                         gyro_rad_s=(0.0, 0.0, rate_z_rad_s))


def _verdicts(est: MadgwickEstimator, samples: Iterator[Sample]) -> list[tuple[float, bool]]:
    """(time s, handed out) per gyro step."""
    out = []
    for s in samples:
        for e in est.process(s):
            assert isinstance(e, (AttitudeEstimate, RejectedEstimate))
            if isinstance(e, RejectedEstimate):
                assert e.flags == EstimateFlag.UNSETTLED
            out.append((e.t_ns / 1e9, isinstance(e, AttitudeEstimate)))
    return out


def test_an_ahrs_not_told_the_board_moved_hands_out_its_first_attitude() -> None:
    verdicts = _verdicts(MadgwickEstimator(), _board(0.0, 0.1, 0.0))
    assert verdicts and all(valid for _, valid in verdicts)


def test_a_start_in_motion_is_withheld_until_the_accelerometer_confirmed_it_for_a_second(
        ) -> None:
    est = MadgwickEstimator()
    est.moving_at_start(0)
    verdicts = _verdicts(est, _board(0.0, 1.5, 0.0))
    first_valid = next(t for t, valid in verdicts if valid)
    assert 1.0 <= first_valid < 1.1
    assert all(not valid for t, valid in verdicts if t < first_valid)
    assert all(valid for t, valid in verdicts if t >= first_valid)
    assert est.diagnostics()["start_check"]["withheld"] == sum(
        not valid for _, valid in verdicts)


def test_a_confirmation_expires_when_no_reading_can_tell_for_two_seconds() -> None:
    """Turning at 10 deg/s no reading can tell, and the unmeasured gyro offset may drift the
    attitude meanwhile: handed out for 2 s after the last confirming reading, then withheld."""
    est = MadgwickEstimator()
    est.moving_at_start(0)
    _verdicts(est, _board(0.0, 1.5, 0.0))
    verdicts = _verdicts(est, _board(1.5, 3.0, math.radians(10.0)))
    last_valid = max(t for t, valid in verdicts if valid)
    assert 3.45 < last_valid <= 3.5
    assert all(not valid for t, valid in verdicts if t > last_valid)
    assert est.diagnostics()["start_check"]["expired"] == 1
