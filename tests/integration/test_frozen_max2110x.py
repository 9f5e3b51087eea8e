"""A MAX21105 whose measurement engine hangs in flight (the seed RC board), through the
fault-injection interface; found by the soak on every bundled board
(tests/benchmarks/soak.py): the driver waited for 50 identical frames (0.25 s at 200 Hz),
and in a turbulent cruise the frozen frames were off the truth from the 13th on."""

from __future__ import annotations

from imuhal.core.samples import GyroSample, SampleFlag
from imuhal.emulation import open_emulated
from imuhal.emulation.faults import FrozenData
from imuhal.plugins.manager import load_registry
from imuhal.profile.bundled import bundled_profiles
from imuhal.profile.loader import load_profile

FROZEN_FROM_S = 20.0


def test_a_frozen_max21105_is_flagged_within_a_twentieth_of_a_second() -> None:
    """10 identical frames at 200 Hz (the soak found the frozen frames off the truth from
    the 13th on in a turbulent cruise); nothing after the flag is valid while it lasts."""
    registry = load_registry()
    profile = load_profile(bundled_profiles()["seed-rc-vario.yaml"], registry)
    with open_emulated(profile, registry, seed=1,
                       faults=[FrozenData(device="imu", start_s=FROZEN_FROM_S,
                                          end_s=FROZEN_FROM_S + 1.0)]) as p:
        gyro = [e for e in p.events(FROZEN_FROM_S + 1.0)
                if isinstance(e, GyroSample) and e.t_ns >= FROZEN_FROM_S * 1e9]
    first = next(s.t_ns / 1e9 for s in gyro if s.flags & SampleFlag.FROZEN)
    assert first <= FROZEN_FROM_S + 0.055
    assert not [s for s in gyro if first < s.t_ns / 1e9 < FROZEN_FROM_S + 1.0 and s.valid]
