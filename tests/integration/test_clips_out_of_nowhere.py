"""Wild gyro words through a launch run leave no attitude far off (issue 26: the fault matrix
at 10 % ``wild_value`` handed out 220 of 923 attitudes on gy91 more than 10 deg off, worst
29.5, all in the ``thermal`` scenario's launch run).

Each word is 1000 times the full scale about the pitch axis, straight out of a rate well
inside the range. When the emulated chip put it out at its rail (flagged SATURATED), it was
integrated at the full scale (as a rotation beyond the range would be), each put up to
2.5 deg of pitch in, and the angular-rate recovery's pull then turned the tilt towards an
accelerometer reading the launch run's push: the errors grew word by word. A rate does not
grow by the whole range in one sample, so the AHRS drops such a clip as a corrupt word
(``RECOVERY_RAMP``, tests/filters/test_angular_rate_recovery.py). The emulated MPU-9250 now
runs the word through its DLPF as the chip does (the ADC cuts it at the rail, the 41 Hz
filter takes 0.72 of that into an output in range): the driver flags that output and the
trace after it FILTER_SETTLING, and none reaches the AHRS.
"""

from __future__ import annotations

import math

from imuhal.emulation import open_emulated
from imuhal.emulation.faults import WildValue
from imuhal.estimation.outputs import AttitudeEstimate
from imuhal.plugins.manager import load_registry
from imuhal.profile.bundled import bundled_profiles
from imuhal.profile.loader import load_profile
from imuhal_filters.common.quat import tilt_error_deg

FLIGHT_S = 8.0
WORDS_S = [round(1.075 + 0.15 * k, 3) for k in range(46)]
"""A gyro word every 0.15 s from 1.075 s to 7.825 s, as the fault matrix's 10 % plan puts
them on gy91's IMU (every third of its wild values is a gyro word)."""
TILT_MARGIN_DEG = 10.0
"""The fault matrix's count of attitudes far off (tests/benchmarks/fault_truth.py)."""


def test_wild_gyro_words_in_the_launch_run_leave_no_attitude_far_off() -> None:
    registry = load_registry()
    profile = load_profile(bundled_profiles()["gy91.yaml"], registry)
    faults = [WildValue(device="imu", start_s=t, channel="gyro", axis=1,
                        value=1000.0 * math.radians(500.0), hold_s=0.003) for t in WORDS_S]
    worst, handed_out = 0.0, 0
    with open_emulated(profile, registry, seed=1, faults=faults) as pipeline:
        truth = pipeline.board.scenario.truth  # type: ignore[union-attr]  # emulated board
        for event in pipeline.events(FLIGHT_S):
            if isinstance(event, AttitudeEstimate) and event.t_ns >= 1e9:
                handed_out += 1
                worst = max(worst, tilt_error_deg(
                    event.q_body_to_ned, tuple(truth(event.t_ns / 1e9).q_body_to_ned)))
        ahrs = next(r.estimator for r in pipeline.estimators if r.name == "ahrs")
        recovery = ahrs.diagnostics()["angular_rate_recovery"]
    # none was taken for a rotation: the chip's low-pass hides the rail (each word is an
    # output 0.72 of the way there), the driver sees it by undoing the filter and flags it
    # FILTER_SETTLING, so no word reaches the AHRS as a clip
    assert recovery.get("unramped_clips", 0) == 0
    assert recovery["recoveries"] == 0 and recovery["clipped_samples"] == 0
    assert handed_out > 500
    assert worst <= TILT_MARGIN_DEG
