"""A wild gyro word the chip clips at its rail, in the first read after a host stall, is
never handed out as an attitude (issue 26, the fault matrix on seed-gps-vario at 10 %).

The angular-rate recovery integrates a clipped reading as a rotation at the rail over its
step (Fusion's recovery: a rotation beyond the range loses less that way than as a gap). After
a 46 ms stall that step put 45 deg of pitch in, and the estimate was handed out: the recovery
compared the accelerometer with the attitude from before the step. It now judges the attitude
the step hands out, so it is withheld (UNSETTLED) until the pull has brought it back.
"""

from __future__ import annotations

from imuhal.emulation import open_emulated
from imuhal.emulation.faults import HostStall, WildValue
from imuhal.estimation.outputs import AttitudeEstimate, RejectedEstimate
from imuhal.plugins.manager import load_registry
from imuhal.profile.bundled import bundled_profiles
from imuhal.profile.loader import load_profile
from imuhal_filters.common.quat import tilt_error_deg

WILD_S = 3.175
"""A gyro word of 1000 times the full scale about the pitch axis, where the fault matrix's
10 % plan puts one: the host stall before it (20 ms stalls at 5 Hz on each of the four
devices) delays the read that finds it by 46 ms."""
TILT_MARGIN_DEG = 10.0
"""The fault matrix's count of attitudes far off (tests/benchmarks/fault_truth.py)."""


def test_a_clipped_wild_gyro_word_after_a_stall_is_withheld_not_handed_out() -> None:
    registry = load_registry()
    profile = load_profile(bundled_profiles()["seed-gps-vario.yaml"], registry)
    faults = [HostStall(device=d, start_s=1.0, stall_s=0.02, rate_hz=5.0)
              for d in ("imu", "mag", "baro", "gps")]
    faults.append(WildValue(device="imu", start_s=WILD_S, channel="gyro", axis=1,
                            value=17436.264917484816, hold_s=0.003))
    worst, withheld = 0.0, 0
    with open_emulated(profile, registry, seed=1, faults=faults) as pipeline:
        truth = pipeline.board.scenario.truth  # type: ignore[union-attr]  # emulated board
        for event in pipeline.events(WILD_S + 0.3):
            if getattr(event, "t_ns", 0) < WILD_S * 1e9:
                continue
            if isinstance(event, AttitudeEstimate):
                worst = max(worst, tilt_error_deg(
                    event.q_body_to_ned, tuple(truth(event.t_ns / 1e9).q_body_to_ned)))
            elif isinstance(event, RejectedEstimate) and event.kind == "attitude":
                withheld += 1
    assert withheld > 0  # the clipped word did reach the AHRS
    assert worst <= TILT_MARGIN_DEG
