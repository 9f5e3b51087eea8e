"""A poll that comes due while the pipeline's one thread is held (a host stall, another
device's recovery) happens when the thread is free, never at its old due time; through the
fault-injection interface. Found by the soak on every bundled board
(tests/benchmarks/soak.py), before the fix:

- gy91: the MPU-9250's recovery held the thread 0.22-0.44 s; the BMP280 was then polled
  once per missed output slot at each slot's old time, handing out the one output it held
  up to 21 times, stamped 20 ms apart inside the time nothing was read, all valid (3 of them
  more than the error model off the truth in the hour's first 1,320 s);
- seed-gps-vario: the GNSS driver's reconfiguration after a receiver restart held the
  thread 1.25-2.08 s; the emulated board then handed the MS5611 the world of the poll's due
  time (``EmulatedBoard.before_poll``), two seconds old, and its pressure (14-37 Pa off) was
  stamped at the conversion's real end, valid; the vario followed it (-4.5 to -8.5 m/s).

The boards' ``before_poll`` now put a late poll at the clock (a recording keeps it, so a
replay polls then too), and the pipeline puts a poll of a chip with its own output rate off
to the next point of its poll grid (``Pipeline._on_phase``): its reading keeps the phase,
and the frame ledger's count, of the polls before it."""

from __future__ import annotations

import pytest

from imuhal.core.samples import Sample
from imuhal.emulation import open_emulated
from imuhal.emulation.faults import HostStall
from imuhal.plugins.manager import load_registry
from imuhal.profile.bundled import bundled_profiles
from imuhal.profile.loader import load_profile

STALL_S = 0.3
STALLS_AT_S = (2.0, 3.0, 4.0)


@pytest.fixture(scope="module")
def stalled_gy91() -> list[Sample]:
    """A gy91 whose host stalls 0.3 s before an IMU poll at 2, 3 and 4 s."""
    registry = load_registry()
    profile = load_profile(bundled_profiles()["gy91.yaml"], registry)
    stall = HostStall(device="imu", start_s=STALLS_AT_S[0], end_s=STALLS_AT_S[-1] + 0.5,
                      every_s=1.0, stall_s=STALL_S)
    with open_emulated(profile, registry, seed=1, faults=[stall]) as p:
        return [e for e in p.events(5.0) if isinstance(e, Sample)]


def test_no_reading_is_stamped_while_the_host_was_stalled(stalled_gy91: list[Sample]) -> None:
    """The stall begins at the first IMU poll due at or after each instant (200 Hz: within
    5 ms of it); nothing can be read until it ends."""
    inside = [(round(s.t_ns / 1e9, 4), s.device, s.channel.value) for s in stalled_gy91
              if any(at + 0.006 < s.t_ns / 1e9 < at + STALL_S for at in STALLS_AT_S)]
    assert inside == []
