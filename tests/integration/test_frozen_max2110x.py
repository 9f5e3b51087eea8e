"""A MAX21105 whose measurement engine hangs in flight (the seed RC board), through the
fault-injection interface; found by the soak on every bundled board
(tests/benchmarks/soak.py): the driver waited for 50 identical frames (0.25 s at 200 Hz),
and in a turbulent cruise the frozen gyro was off the truth long before that."""

from __future__ import annotations

from imuhal.core.samples import GyroSample, SampleFlag
from imuhal.emulation import open_emulated
from imuhal.emulation.faults import FrozenData
from imuhal.plugins.manager import load_registry
from imuhal.profile.bundled import bundled_profiles
from imuhal.profile.loader import load_profile

FROZEN_FROM_S = 20.0


def test_a_frozen_max21105_is_flagged_within_a_tenth_of_a_second() -> None:
    """20 identical frames at 200 Hz; the frames before are the hung engine's first output,
    repeated, and within its noise of what the chip measured then."""
    registry = load_registry()
    profile = load_profile(bundled_profiles()["seed-rc-vario.yaml"], registry)
    with open_emulated(profile, registry, seed=1,
                       faults=[FrozenData(device="imu", start_s=FROZEN_FROM_S,
                                          end_s=FROZEN_FROM_S + 1.0)]) as p:
        gyro = [e for e in p.events(FROZEN_FROM_S + 1.0)
                if isinstance(e, GyroSample) and e.t_ns >= FROZEN_FROM_S * 1e9]
    first = next(s.t_ns / 1e9 for s in gyro if s.flags & SampleFlag.FROZEN)
    assert first <= FROZEN_FROM_S + 0.105
    assert not [s for s in gyro if first < s.t_ns / 1e9 < FROZEN_FROM_S + 1.0 and s.valid]
