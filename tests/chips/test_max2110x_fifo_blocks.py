"""The MAX21100 driver decodes a FIFO read at once into its blocks' arrays (``poll_blocks``,
read: fifo): the same floats and flags as decoding it frame by frame, shown as for the
MPU-9250 (tests/chips/test_mpu9250_fifo_blocks.py) on the seed paraglider board: every event
of the same flight with the base class's ``poll_blocks`` equal bit for bit, through
saturation, filter memory, frozen frames (those reads go frame by frame) and overflows.
"""

from __future__ import annotations

from collections import Counter

import pytest
from tests.support.fifo_boards import QUICK_ROLL, imu_read_from_fifo

from imuhal.core.samples import AccelSample, GyroSample, SampleFlag
from imuhal.drivers.base import Driver
from imuhal.emulation import open_emulated
from imuhal.emulation.faults import HostStall
from imuhal.plugins.manager import Registry, load_registry
from imuhal.profile.model import BoardProfile
from imuhal_chips.max2110x.driver import Max2110xDriver


@pytest.fixture(scope="module")
def registry() -> Registry:
    return load_registry()


def _seed_fifo(registry: Registry) -> BoardProfile:
    return imu_read_from_fifo(registry, "seed-paraglider-vario.yaml", 8, gyro_range_dps=250)


def _flight(registry: Registry, *, ideal: bool) -> list[object]:
    faults = [HostStall(device="imu", start_s=3.5, every_s=1.0, stall_s=0.3)]
    with open_emulated(_seed_fifo(registry), registry, scenario="tumble",
                       scenario_params=QUICK_ROLL, seed=3, faults=faults,
                       sensor_errors=not ideal, calibrated=not ideal) as pipeline:
        events: list[object] = list(pipeline.events(5.0))
        assert pipeline.devices["imu"].driver.health.fifo_overflows > 0
    return events


@pytest.mark.parametrize("ideal", [False, True], ids=["noisy", "ideal"])
def test_a_read_decoded_at_once_gives_the_events_of_frame_by_frame(
        registry: Registry, monkeypatch: pytest.MonkeyPatch, ideal: bool) -> None:
    arrays = [repr(e) for e in _flight(registry, ideal=ideal)]
    monkeypatch.setattr(Max2110xDriver, "poll_blocks", Driver.poll_blocks)
    frames = [repr(e) for e in _flight(registry, ideal=ideal)]
    assert len(arrays) == len(frames) > 2000
    assert arrays == frames


def test_the_flights_meet_every_case_the_arrays_decode(registry: Registry) -> None:
    """The comparison above cannot pass by missing a case."""
    flags: Counter[str] = Counter()
    for ideal in (False, True):
        for e in _flight(registry, ideal=ideal):
            if isinstance(e, AccelSample | GyroSample) and e.device == "imu":
                for f in (SampleFlag.SATURATED, SampleFlag.FILTER_SETTLING, SampleFlag.FROZEN):
                    flags[f"{ideal} {f.name}"] += bool(e.flags & f)
    assert flags["False SATURATED"] > 0 and flags["False FILTER_SETTLING"] > 0
    assert flags["True FROZEN"] > 0
