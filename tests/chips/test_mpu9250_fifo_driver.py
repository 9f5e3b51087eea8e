"""The MPU-9250 driver's FIFO reader (read: fifo; issue 25 item 2), on the emulated gy91
board through the documented fault interface: a host stall shorter than the FIFO loses
nothing, a longer one is a counted overflow and a reset with no wrong frame, and frames are
back-dated to the chip's instants."""

from __future__ import annotations

import struct
from bisect import bisect_right

import numpy as np
import pytest

from imuhal.core.samples import GyroSample
from imuhal.emulation import open_emulated
from imuhal.emulation.faults import HostStall
from imuhal.pipeline import Pipeline
from imuhal.plugins.manager import Registry, load_registry
from imuhal.profile.bundled import bundled_profiles
from imuhal.profile.loader import load_profile
from imuhal.profile.model import BoardProfile
from imuhal_chips.mpu9250.fifo import frames_consistent

PERIOD_NS = 5_000_000  # the gy91's 200 Hz
MOVING_NS = 2_100_000_000  # ``tumble`` rests for its first 2 s


@pytest.fixture(scope="module")
def registry() -> Registry:
    return load_registry()


def _gy91(registry: Registry, read: str, **imu: object) -> BoardProfile:
    profile = load_profile(bundled_profiles()["gy91.yaml"], registry)
    device = profile.devices["imu"]
    settings = {**device.settings, "read": read, **imu}
    return profile.model_copy(update={"devices": {
        **profile.devices, "imu": device.model_copy(update={"settings": settings})}})


def _run(registry: Registry, read: str, stall_s: float, scenario: str = "tumble",
         seconds: float = 4.5, *, ideal: bool = True) -> tuple[Pipeline, list[GyroSample]]:
    """``ideal``: chips without noise (the samples are then the truth to one LSB; at rest
    an ideal chip repeats its frame, flagged FROZEN)."""
    faults = [HostStall(device="imu", start_s=1.0, every_s=1.0, stall_s=stall_s)]
    with open_emulated(_gy91(registry, read), registry, scenario=scenario, seed=1,
                       faults=faults, sensor_errors=not ideal, calibrated=False) as p:
        gyros = [e for e in p.events(seconds)
                 if isinstance(e, GyroSample) and e.device == "imu" and e.valid]
    return p, gyros


def test_a_stall_of_80_percent_of_the_fifo_loses_nothing_in_fifo_mode(
        registry: Registry) -> None:
    """36 frames of 14 bytes fit in 512 bytes (180 ms at 200 Hz); 144 ms stalls at 1, 2, 3
    and 4 s, each over before the flight ends (a poll put off past the end of a run is not
    made, so the frames of a stall that outlasts it are never counted)."""
    fifo, _ = _run(registry, "fifo", 0.144, "thermal", 4.5, ideal=False)
    polled, _ = _run(registry, "registers", 0.144, "thermal", 4.5, ideal=False)
    frames = fifo.summary().frames["imu"]
    assert frames["delivered"] == frames["produced"] > 700
    # polling, the same flight: the 28 or 29 frames each of the 4 stalls spans are lost
    assert 4 * 28 <= polled.summary().frames["imu"]["lost_host_stall"] <= 4 * 29


def test_a_stall_longer_than_the_fifo_is_a_counted_overflow_and_no_frame_is_wrong(
        registry: Registry) -> None:
    p, gyros = _run(registry, "fifo", 0.3, "thermal", ideal=False)
    frames = p.summary().frames["imu"]
    assert frames["lost_fifo_overflow"] > 0
    assert p.devices["imu"].driver.health.fifo_overflows >= 3  # the stalls at 2, 3 and 4 s
    ledger = p.devices["imu"].ledger
    assert ledger is not None
    chip = p.board.emulators["imu"]
    instants = np.asarray(chip.measured_ns)
    # frames the chip measured from the first to the last delivered one of each segment
    # (stamps lie within microseconds of their instants, before or after them)
    assert [n for *_, n in ledger.all_segments()] == [
        int(np.sum((instants > a - PERIOD_NS // 2) & (instants < b + PERIOD_NS // 2)))
        for a, b, _ in ledger.all_segments()]
    assert frames["delivered"] == len(gyros)


def test_frames_are_stamped_at_their_measurement_instants_a_period_apart(
        registry: Registry) -> None:
    p, gyros = _run(registry, "fifo", 0.1)
    moving = [g for g in gyros if g.t_ns > MOVING_NS]
    assert len(moving) > 400
    steps = np.diff([g.t_ns for g in moving])
    assert np.all(np.abs(steps - PERIOD_NS) <= PERIOD_NS // 20)
    errors_ns = _assert_each_sample_is_its_instants_truth(p, moving)
    assert np.max(np.abs(errors_ns)) < 50_000


def _assert_each_sample_is_its_instants_truth(p: Pipeline,
                                              gyros: list[GyroSample]) -> list[int]:
    """Each sample equals the truth at the chip instant nearest its stamp within one LSB: a
    frame out of place or shifted would not. Returns each stamp minus that instant."""
    chip = p.board.emulators["imu"]
    lsb = chip.resolution(GyroSample.channel)
    rotation = np.asarray(p.devices["imu"].chip_to_body, dtype=float)
    errors = []
    for g in gyros:
        i = bisect_right(chip.measured_ns, g.t_ns)
        instant = min(chip.measured_ns[max(i - 1, 0):i + 1], key=lambda t: abs(t - g.t_ns))
        truth = np.asarray(p.board.truth_at(instant).angular_rate_body_rad_s)
        assert np.max(np.abs(rotation @ np.asarray(g.gyro_rad_s) - truth)) <= lsb, g.t_ns
        errors.append(g.t_ns - instant)
    return errors


def test_a_temperature_jump_between_frames_is_a_corrupt_fifo() -> None:
    frame = struct.pack(">7h", 0, 0, 8192, 1000, 0, 0, 0)
    shifted = frame[1:] + frame[:1]  # one byte lost: every word misaligned
    assert frames_consistent([frame, frame])
    assert not frames_consistent([frame, shifted])


