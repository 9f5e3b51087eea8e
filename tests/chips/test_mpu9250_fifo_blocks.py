"""The MPU-9250 driver decodes a FIFO burst at once into its blocks' arrays
(``poll_blocks``, read: fifo): the same floats and flags as decoding it frame by frame.

The reference is the same emulated GY-91 flight (same seed) with the base class's
``poll_blocks`` (the driver's ``poll``: one frame at a time into samples, then grouped):
every event the pipeline emits (each sample, each estimate, diagnostics included) is equal
bit for bit (``repr`` writes every float so that it round-trips). The flights include
saturated frames (a roll faster than the gyro's range), the chip's filter memory after
them, frozen frames of an ideal chip at rest (that burst goes frame by frame) and FIFO
overflows from host stalls.
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
from imuhal_chips.mpu9250.driver import MPU9250Driver


@pytest.fixture(scope="module")
def registry() -> Registry:
    return load_registry()


def _gy91_fifo(registry: Registry, gyro_range_dps: int) -> BoardProfile:
    return imu_read_from_fifo(registry, "gy91.yaml", 10, gyro_range_dps=gyro_range_dps)


def _events(registry: Registry, *, ideal: bool) -> list[str]:
    faults = [HostStall(device="imu", start_s=3.5, every_s=1.0, stall_s=0.3)]
    with open_emulated(_gy91_fifo(registry, 250), registry, scenario="tumble",
                       scenario_params=QUICK_ROLL, seed=3, faults=faults,
                       sensor_errors=not ideal, calibrated=not ideal) as pipeline:
        return [repr(e) for e in pipeline.events(5.0)]


@pytest.mark.parametrize("ideal", [False, True], ids=["noisy", "ideal"])
def test_a_burst_decoded_at_once_gives_the_events_of_frame_by_frame(
        registry: Registry, monkeypatch: pytest.MonkeyPatch, ideal: bool) -> None:
    arrays = _events(registry, ideal=ideal)
    monkeypatch.setattr(MPU9250Driver, "poll_blocks", Driver.poll_blocks)
    frames = _events(registry, ideal=ideal)
    assert len(arrays) == len(frames) > 2000
    assert arrays == frames


def test_the_flights_meet_every_case_the_arrays_decode(registry: Registry) -> None:
    """The comparison above cannot pass by missing a case."""
    flags: Counter[str] = Counter()
    for ideal in (False, True):
        faults = [HostStall(device="imu", start_s=3.5, every_s=1.0, stall_s=0.3)]
        with open_emulated(_gy91_fifo(registry, 250), registry, scenario="tumble",
                           scenario_params=QUICK_ROLL, seed=3, faults=faults,
                           sensor_errors=not ideal, calibrated=not ideal) as pipeline:
            for e in pipeline.events(5.0):
                if isinstance(e, AccelSample | GyroSample) and e.device == "imu":
                    for f in (SampleFlag.SATURATED, SampleFlag.FILTER_SETTLING,
                              SampleFlag.FROZEN):
                        flags[f"{ideal} {f.name}"] += bool(e.flags & f)
            overflows = pipeline.devices["imu"].driver.health.fifo_overflows
            assert overflows > 0
    assert flags["False SATURATED"] > 0 and flags["False FILTER_SETTLING"] > 0
    assert flags["True FROZEN"] > 0


