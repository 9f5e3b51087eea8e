"""The seed board read from its MAX21100's FIFO emits the same events, bit for bit, whether
the chip latches a fill's planned measurements at once (``fast_paths``, the
default) or one by one, with the faults of the documented interface (imuhal.emulation.faults)
in force, starting inside fills:

- on the magnetometer behind the MAX21100's slave auto-read (a chip reset and bus errors):
  the auto-reads of a fill latched at once follow its accelerometer measurements in turn,
  so each fault meets the same transactions;
- a host stall (on the barometer's polls: the one clock moves, every device waits), which
  overflows the FIFO: the frames that do not fit are dropped as one by one;
- on the MAX21100 itself (a wild value, stuck data-ready): a device with faults scheduled
  is never planned, so its fills are latched one by one and each fault acts at the
  measurements it acts at today; and it does act in FIFO mode (the flight differs from the
  flight without it).

The drivers run on poll plan 2 (imuhal.core.poll_plan), where the host reads the MAX21100
every 8 periods only: from plan 3 its driver reads the slave's copy a guard after every
instant between FIFO reads, so the chip latches at most one instant per host access and a
fill at once comes only with a host stall (3 in this flight's faults elsewhere, 0 without
faults).
"""

from __future__ import annotations

from collections.abc import Sequence

import pytest

from imuhal.emulation import open_emulated
from imuhal.emulation.board import EmulatedBoard
from imuhal.emulation.faults import BusErrors, ChipReset, HostStall, StuckDataReady, WildValue
from imuhal.plugins.manager import Registry, load_registry
from imuhal.profile.bundled import bundled_profiles
from imuhal.profile.faults import FaultSpec
from imuhal.profile.loader import load_profile
from imuhal.profile.model import BoardProfile

SECONDS = 3.0


@pytest.fixture(scope="module")
def registry() -> Registry:
    return load_registry()


def _seed_fifo(registry: Registry) -> BoardProfile:
    profile = load_profile(bundled_profiles()["seed-paraglider-vario.yaml"], registry)
    device = profile.devices["imu"]
    settings = {**device.settings, "read": "fifo", "fifo_frames": 8}
    return profile.model_copy(update={"devices": {
        **profile.devices, "imu": device.model_copy(update={"settings": settings})}})


def _fly(registry: Registry, faults: Sequence[FaultSpec], *, at_once: bool
         ) -> tuple[list[str], int, int, list[str]]:
    """(every event's repr, fills latched at once, FIFO frames dropped, the fault log)
    over ``SECONDS``, circling from the start."""
    with open_emulated(_seed_fifo(registry), registry, scenario="thermal", seed=4,
                       scenario_params={"launch_s": 0.0, "schedule": [[0.0, 3.5]]},
                       calibrated=False, faults=faults, poll_plan=2) as p:
        board = EmulatedBoard.of(p)
        imu = board.emulators["imu"]
        imu.fast_paths = at_once
        events = [repr(e) for e in p.events(SECONDS)]
        return (events, imu.fills_latched_at_once, imu.fifo.frames_dropped,
                list(board.faults.log.events))


ELSEWHERE = (ChipReset(device="mag", start_s=1.0131),
             BusErrors(device="mag", rate=0.05, start_s=0.5, end_s=2.5),
             HostStall(device="baro", stall_s=0.07, every_s=0.9, start_s=0.6017, end_s=2.9))
"""Faults on other devices than the MAX21100, starting inside its fills (they start at the
first poll or line transfer at or after ``start_s``)."""


def test_fills_latched_at_once_meet_faults_elsewhere_as_fills_latched_one_by_one(
        registry: Registry) -> None:
    at_once = _fly(registry, ELSEWHERE, at_once=True)
    one_by_one = _fly(registry, ELSEWHERE, at_once=False)
    assert at_once[0] == one_by_one[0]
    assert at_once[2:] == one_by_one[2:]
    assert at_once[1] > 30 and one_by_one[1] == 0  # the fast path ran, the reference not
    assert at_once[2] > 0  # the stalls overflowed the FIFO
    assert any("mag: chip reset" in line for line in at_once[3])


ON_THE_IMU = (WildValue(device="imu", channel="gyro", axis=1, value=50.0, start_s=1.0131,
                        end_s=1.0291),
              StuckDataReady(device="imu", start_s=2.0017, end_s=2.1))
"""Faults on the MAX21100 itself, starting inside its fills."""


def test_faults_on_the_fifo_chip_act_in_fifo_mode_as_one_by_one(registry: Registry) -> None:
    at_once = _fly(registry, ON_THE_IMU, at_once=True)
    one_by_one = _fly(registry, ON_THE_IMU, at_once=False)
    assert at_once == one_by_one
    assert at_once[1] == 0  # a device with faults scheduled is not planned
    clean = _fly(registry, (), at_once=True)
    assert clean[1] > 30
    # the faults act: the wild rate's frames (from 1.0131 s, through the chip's low-pass:
    # 4 outputs rise to 0.76 of the rail) are rail inputs the driver sees by undoing the
    # filter, and the hung chip's empty FIFO is flagged stale (until the driver's reset)
    for flag in ("FILTER_SETTLING", "STALE"):
        assert _gyro_flagged(at_once[0], flag) and not _gyro_flagged(clean[0], flag)


def _gyro_flagged(events: list[str], flag: str) -> list[str]:
    return [e for e in events if e.startswith("GyroSample") and flag in e.split("flags=")[1]
            .split(">")[0]]
