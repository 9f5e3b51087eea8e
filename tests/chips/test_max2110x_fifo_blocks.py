"""The MAX21100 driver decodes a FIFO read at once into its blocks' arrays (``poll_blocks``,
read: fifo): the same floats and flags as decoding it frame by frame.

The reference is the same emulated seed paraglider flight (same seed) with the base class's
``poll_blocks`` (the driver's ``poll``: one frame at a time into samples, then grouped):
every event the pipeline emits (each sample, each estimate, diagnostics included) is equal
bit for bit (``repr`` writes every float so that it round-trips). The flights include
saturated frames (a roll faster than the gyro's range), the chip's filter memory after
them, frozen frames of an ideal chip at rest (that read goes frame by frame) and FIFO
overflows from host stalls.
"""

from __future__ import annotations

from collections import Counter

import pytest

from imuhal.core.samples import AccelSample, GyroSample, SampleFlag
from imuhal.drivers.base import Driver
from imuhal.emulation import open_emulated
from imuhal.emulation.faults import HostStall
from imuhal.plugins.manager import Registry, load_registry
from imuhal.profile.bundled import bundled_profiles
from imuhal.profile.loader import load_profile
from imuhal.profile.model import BoardProfile
from imuhal_chips.max2110x.driver import Max2110xDriver

QUICK_ROLL = {"axes": [[1.0, 0.0, 0.0]], "rotation_s": 0.8, "ramp_s": 0.2, "hold_s": 2.0,
              "free_tumble_s": 0.0}
"""One full roll in 0.8 s after 2 s still: up to about 10 rad/s, beyond +-250 deg/s."""


@pytest.fixture(scope="module")
def registry() -> Registry:
    return load_registry()


def _seed_fifo(registry: Registry) -> BoardProfile:
    profile = load_profile(bundled_profiles()["seed-paraglider-vario.yaml"], registry)
    device = profile.devices["imu"]
    settings = {**device.settings, "read": "fifo", "fifo_frames": 8, "gyro_range_dps": 250}
    return profile.model_copy(update={"devices": {
        **profile.devices, "imu": device.model_copy(update={"settings": settings})}})


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
