"""A wild gyro word the chip clips at its rail, in the first read after a host stall, is
never handed out as an attitude (issue 26, the fault matrix on seed-gps-vario at 10 %).

When the emulated chip put the word out at its rail, straight out of a slow glide, the rate
would have grown by the whole range in one sample, which no vehicle does, so the AHRS drops
it as a corrupt word (``RECOVERY_RAMP``) instead of integrating it at the full scale.
Integrated, the step over the 46 ms the stall delayed the read put 45 deg of pitch in; the
recovery then withheld the attitude until its pull had brought it back, and still handed
out estimates 5.7 deg off. The emulated MPU-9250 now runs the word through its DLPF (an
output 0.72 of the way to the rail, in range): read after the outputs the stall left
unseen, its mean input over the gap is not at the rail, and it went out valid (36 deg of
tilt), until the driver held an output after a gap against the change before it
(``LowPassWatch``): it is FILTER_SETTLING and never reaches the AHRS.
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
TILT_BOUND_DEG = 4.0
"""The filter's own tilt error in the 0.3 s after WILD_S of the same flight without the wild
word (3.1 deg: the launch run's push), plus a degree."""


def test_a_clipped_wild_gyro_word_after_a_stall_is_dropped_not_integrated() -> None:
    registry = load_registry()
    profile = load_profile(bundled_profiles()["seed-gps-vario.yaml"], registry)
    faults = [HostStall(device=d, start_s=1.0, stall_s=0.02, rate_hz=5.0)
              for d in ("imu", "mag", "baro", "gps")]
    faults.append(WildValue(device="imu", start_s=WILD_S, channel="gyro", axis=1,
                            value=17436.264917484816, hold_s=0.003))
    worst, withheld, handed_out = 0.0, 0, 0
    with open_emulated(profile, registry, seed=1, faults=faults) as pipeline:
        truth = pipeline.board.scenario.truth  # type: ignore[union-attr]  # emulated board
        for event in pipeline.events(WILD_S + 0.3):
            if getattr(event, "t_ns", 0) < WILD_S * 1e9:
                continue
            if isinstance(event, AttitudeEstimate):
                handed_out += 1
                worst = max(worst, tilt_error_deg(
                    event.q_body_to_ned, tuple(truth(event.t_ns / 1e9).q_body_to_ned)))
            elif isinstance(event, RejectedEstimate) and event.kind == "attitude":
                withheld += 1
        ahrs = next(r.estimator for r in pipeline.estimators if r.name == "ahrs")
        recovery = ahrs.diagnostics()["angular_rate_recovery"]
    # the DLPF hides the rail (an output 0.72 of the way there, read after the stall's
    # unseen outputs): the driver flags it FILTER_SETTLING, and no clip reaches the AHRS
    assert recovery.get("unramped_clips", 0) == 0
    assert recovery["clipped_samples"] == 0 and recovery["recoveries"] == 0
    assert withheld == 0 and handed_out > 50
    assert worst <= TILT_BOUND_DEG
