"""The AK8963 through the MPU-9250's FIFO (issue 25): on the seed-gps-vario with the MPU
reading its FIFO and the AK8963 auto-read by slave 0, each FIFO frame carries the slave's
ST1..ST2 copy of its own sample instant; host stalls of 80 % of the FIFO's depth lose no IMU
frame and no magnetometer measurement, each stamped at the MPU sample that copied it
(sensor errors on: an ideal chip in steady flight repeats its frames, which the drivers
rightly flag FROZEN)."""

from __future__ import annotations

from bisect import bisect_right

import numpy as np
import pytest

from imuhal.core.samples import GyroSample, MagSample
from imuhal.core.streams import TimeSource
from imuhal.emulation import open_emulated
from imuhal.emulation.faults import HostStall
from imuhal.pipeline import Pipeline
from imuhal.plugins.manager import Registry, load_registry
from imuhal.profile.bundled import bundled_profiles
from imuhal.profile.loader import load_profile

STALL_S = 0.092
"""80 % of the FIFO's depth in time: 23 frames of 22 bytes (accel, temperature, gyro and
the AK8963's 8 bytes) in 512, 115 ms at 200 Hz."""


@pytest.fixture(scope="module")
def flight() -> tuple[Pipeline, list[GyroSample], list[MagSample]]:
    registry: Registry = load_registry()
    profile = load_profile(bundled_profiles()["seed-gps-vario.yaml"], registry)
    imu = profile.devices["imu"]
    profile = profile.model_copy(update={"devices": {**profile.devices, "imu": imu.model_copy(
        update={"settings": {**imu.settings, "read": "fifo", "fifo_frames": 1}})}})
    faults = [HostStall(device="imu", start_s=1.0, every_s=1.0, stall_s=STALL_S)]
    with open_emulated(profile, registry, scenario="thermal", seed=3, faults=faults,
                       calibrated=False) as p:
        p.board.emulators["imu"].oscillator_error = 0.015
        p.board.emulators["mag"].oscillator_error = -0.01
        events = list(p.events(6.0))
    gyros = [e for e in events if isinstance(e, GyroSample) and e.valid]
    mags = [e for e in events if isinstance(e, MagSample) and e.valid]
    return p, gyros, mags


def test_stalls_of_80_percent_of_the_fifo_lose_no_imu_frame(
        flight: tuple[Pipeline, list[GyroSample], list[MagSample]]) -> None:
    p, gyros, _ = flight
    frames = p.summary().frames["imu"]
    assert frames["delivered"] == frames["produced"] == len(gyros) > 1000
    chip = p.board.emulators["imu"]
    instants = np.asarray(chip.measured_ns)
    inside = instants[(instants > gyros[0].t_ns - 2_500_000)
                      & (instants < gyros[-1].t_ns + 2_500_000)]
    assert len(inside) == len(gyros)
    errors_us = (np.asarray([g.t_ns for g in gyros]) - inside) / 1e3
    assert np.sqrt(np.mean(errors_us ** 2)) < 50
    assert np.max(np.abs(errors_us)) < 200


def test_each_magnetometer_measurement_arrives_once_stamped_at_its_copy(
        flight: tuple[Pipeline, list[GyroSample], list[MagSample]]) -> None:
    p, _, mags = flight
    ak = p.board.emulators["mag"]
    instants = list(ak.measured_ns)
    # each field is stamped at the MPU sample that copied it: after the AK8963 measured it,
    # within one MPU period
    taken = [instants[bisect_right(instants, m.t_ns + 50_000) - 1] for m in mags]
    assert len(set(taken)) == len(mags)
    lag = np.asarray([m.t_ns for m in mags]) - np.asarray(taken)
    assert np.all((lag > -50_000) & (lag < 5_000_000))
    first, last = instants.index(taken[0]), instants.index(taken[-1])
    assert last - first + 1 == len(mags) > 400  # none lost between the first and the last


def test_fifo_streams_say_their_stamps_come_from_the_chip_clock(
        flight: tuple[Pipeline, list[GyroSample], list[MagSample]]) -> None:
    p, _, _ = flight
    assert {s.time_source for s in p.streams["imu"]} == {TimeSource.CHIP_CLOCK}
