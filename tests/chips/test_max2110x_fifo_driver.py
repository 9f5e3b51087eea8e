"""The MAX21100 driver's FIFO reader (read: fifo; issue 25): on a bare emulated chip, and on
the emulated seed paraglider board through the documented fault interface. A host stall of
80 % of the FIFO's depth loses nothing; a longer one, or a shifted FIFO, is a counted
overflow and a reset with no wrong frame; frames are stamped at the chip's instants."""

from __future__ import annotations

import struct
from bisect import bisect_right

import numpy as np
import pytest
from tests.chips.test_max2110x_driver import AT_REST, Rig, make_rig

from imuhal.core.errors import ConfigurationError
from imuhal.core.samples import AccelSample, GyroSample, Sample
from imuhal.core.streams import TimeSource
from imuhal.emulation import open_emulated
from imuhal.emulation.faults import HostStall
from imuhal.pipeline import Pipeline
from imuhal.plugins.manager import Registry, load_registry
from imuhal.profile.bundled import bundled_profiles
from imuhal.profile.faults import BusErrors
from imuhal.profile.loader import load_profile
from imuhal.profile.model import BoardProfile, InterruptConfig
from imuhal_chips.max2110x.driver import Max21100Driver
from imuhal_chips.max2110x.emulator import Max21100Emulator
from imuhal_chips.max2110x.fifo import frames_aligned

PERIOD_NS = 4_000_000  # the seed paraglider board's 250 Hz
DEPTH_NS = 10 * PERIOD_NS  # 64 words hold 10 frames of 6 words


def _fifo_rig() -> Rig:
    """The inputs dithered by half an LSB before each read (an exact input repeats its
    frame, which the driver flags FROZEN), so each frame reads AT_REST to one LSB."""
    return make_rig(Max21100Driver, Max21100Emulator, read="fifo")


def _valid(samples: list[Sample], cls: type[Sample]) -> list[Sample]:
    return [s for s in samples if isinstance(s, cls) and s.valid]


def pause_past_the_fifo(rig: Rig, depth_ns: int, period_ns: int) -> list[Sample]:
    """0.5 s read, the host away for the FIFO's depth and three periods (data_lost), then
    0.5 s more: the samples of the last 0.5 s."""
    rig.run(0.5)
    rig.clock.sleep((depth_ns + 3 * period_ns) / 1e9)
    rig.next_ns = rig.clock.now_ns()
    return rig.run(0.5)


def shift_the_fifo(rig: Rig) -> list[Sample]:
    """0.5 s read, then one byte popped from FIFO_DATA (a burst cut short) with a frame in
    the FIFO, then 0.5 s more: the samples of the last 0.5 s."""
    rig.run(0.5)
    rig.clock.sleep_until(rig.next_ns)
    rig.bus.transfer(0, bytes((0x80 | 0x40 | 0x3E,)), 1)
    return rig.run(0.5)


def test_fifo_frames_read_the_chips_values_stamped_at_its_instants() -> None:
    rig = _fifo_rig()
    rig.emu.oscillator_error = 0.02
    samples = rig.run(2.0)
    gyros = _valid(samples, GyroSample)
    instants = np.asarray(rig.emu.measured_ns)
    assert len(gyros) == len(_valid(samples, AccelSample)) >= len(instants) - 2
    late = [g for g in gyros if g.t_ns > 1_000_000_000]  # the chip's clock learned
    i = np.searchsorted(instants, [g.t_ns for g in late])
    nearest = np.minimum(np.abs(instants[np.minimum(i, len(instants) - 1)]
                                - [g.t_ns for g in late]),
                         np.abs(instants[i - 1] - [g.t_ns for g in late]))
    assert np.max(nearest) < 50_000
    lsb = rig.emu.resolution(GyroSample.channel)
    assert all(np.max(np.abs(np.subtract(g.gyro_rad_s, AT_REST.angular_rate_rad_s))) <= lsb
               for g in gyros)


def test_the_streams_say_frames_are_stamped_on_the_chips_clock() -> None:
    rig = _fifo_rig()
    gyro = next(s for s in rig.driver.streams() if s.quantity is GyroSample.channel)
    assert gyro.time_source is TimeSource.CHIP_CLOCK and gyro.latency_s == 0.0


def test_a_host_pause_longer_than_the_fifo_is_a_counted_overflow_and_a_reset() -> None:
    rig = _fifo_rig()
    samples = pause_past_the_fifo(rig, DEPTH_NS, PERIOD_NS)
    assert rig.driver.health.fifo_overflows == 1
    assert rig.emu.fifo is not None and rig.emu.fifo.frames_dropped >= 3
    assert len(_valid(samples, GyroSample)) > 100  # frames come again after the reset


def test_a_shifted_fifo_is_reset_and_no_wrong_frame_comes_out() -> None:
    rig = _fifo_rig()
    samples = shift_the_fifo(rig)
    assert rig.driver.health.fifo_overflows == 1
    lsb = rig.emu.resolution(GyroSample.channel)
    gyros = _valid(samples, GyroSample)
    assert len(gyros) > 100
    assert all(np.max(np.abs(np.subtract(g.gyro_rad_s, AT_REST.angular_rate_rad_s))) <= lsb
               for g in gyros)


def test_a_count_of_part_of_a_frame_or_a_word_beyond_full_scale_is_misaligned() -> None:
    frame = struct.pack(">6h", 10, -20, 30, 0, 0, 7500)
    assert frames_aligned(12, [frame, frame])
    assert not frames_aligned(11, [frame])
    assert not frames_aligned(6, [struct.pack(">6h", 10, -20, 30, 0, 0, 30001)])


def test_read_fifo_needs_equal_gyro_and_accel_rates() -> None:
    with pytest.raises((ConfigurationError, ValueError), match="gyro_odr_hz equal"):
        make_rig(Max21100Driver, Max21100Emulator, read="fifo", accel_odr_hz=125)


# --- the seed paraglider board, 4.5 s of `thermal`, one host stall a second from 1 s ----


@pytest.fixture(scope="module")
def registry() -> Registry:
    return load_registry()


def _seed(registry: Registry, read: str, interrupt: InterruptConfig | None) -> BoardProfile:
    profile = load_profile(bundled_profiles()["seed-paraglider-vario.yaml"], registry)
    device = profile.devices["imu"]
    update = {"settings": {**device.settings, "read": read}, "interrupt": interrupt}
    return profile.model_copy(update={"devices": {
        **profile.devices, "imu": device.model_copy(update=update)}})


def _fly(registry: Registry, read: str, stall_s: float, interrupt: InterruptConfig | None = None,
         *, bus_errors: float = 0.0) -> tuple[Pipeline, list[GyroSample]]:
    faults: list[HostStall | BusErrors] = [
        HostStall(device="imu", start_s=1.0, every_s=1.0, stall_s=stall_s)]
    if bus_errors:
        faults.append(BusErrors(device="imu", rate=bus_errors))
    with open_emulated(_seed(registry, read, interrupt), registry, scenario="thermal",
                       seed=1, faults=faults, calibrated=False) as p:
        p.board.emulators["imu"].oscillator_error = 0.02
        gyros = [e for e in p.events(4.5)
                 if isinstance(e, GyroSample) and e.device == "imu" and e.valid]
    return p, gyros


def _chip_count(p: Pipeline) -> int:
    """Frames the chip measured over the ledger's segments (stamps within microseconds of
    their instants, before or after)."""
    ledger = p.devices["imu"].ledger
    assert ledger is not None
    instants = np.asarray(p.board.emulators["imu"].measured_ns)
    return sum(int(np.sum((instants > a - PERIOD_NS // 2) & (instants < b + PERIOD_NS // 2)))
               for a, b, _ in ledger.all_segments())


def test_stalls_of_80_percent_of_the_fifo_lose_no_imu_sample(registry: Registry) -> None:
    fifo, gyros = _fly(registry, "fifo", 0.8 * DEPTH_NS / 1e9)
    frames = fifo.summary().frames["imu"]
    assert frames["delivered"] == frames["produced"] == _chip_count(fifo) == len(gyros) > 900
    # polling, the same flight: the 7 or 8 frames each of the 4 stalls spans are lost
    polled, _ = _fly(registry, "registers", 0.8 * DEPTH_NS / 1e9)
    assert 4 * 7 <= polled.summary().frames["imu"]["lost_host_stall"] <= 4 * 8


def test_stalls_beyond_the_fifo_lose_only_what_it_could_not_keep_counted_as_overflows(
        registry: Registry) -> None:
    p, gyros = _fly(registry, "fifo", 0.092)
    frames = p.summary().frames["imu"]
    assert p.devices["imu"].driver.health.fifo_overflows == 4  # a stall a second from 1 s
    # each 92 ms stall spans 23 or 24 frames of the chip (2 % fast: 3.92 ms); the FIFO kept
    # 10 of them, handed out, and the rest are the overflow's
    assert 4 * 12 <= frames["lost_fifo_overflow"] <= 4 * 15
    assert frames["delivered"] + frames["lost_fifo_overflow"] == frames["produced"]
    assert frames["delivered"] == len(gyros)
    chip = p.board.emulators["imu"]
    for g in gyros[::25]:  # each delivered frame is the one measured at its stamp
        i = bisect_right(chip.measured_ns, g.t_ns)
        instant = min(chip.measured_ns[max(i - 1, 0):i + 1], key=lambda t: abs(t - g.t_ns))
        assert abs(g.t_ns - instant) < 50_000


def test_fifo_read_on_data_ready_edges_stamps_each_frame_at_its_instant_through_stalls(
        registry: Registry) -> None:
    """INT1 drives the line (every second edge reads the FIFO); each frame is stamped with
    its own edge, the instant the chip measured it."""
    line = InterruptConfig(chip="gpiochip0", line=17, edges_per_read=2)
    p, gyros = _fly(registry, "fifo", 0.8 * DEPTH_NS / 1e9, line)
    frames = p.summary().frames["imu"]
    assert frames["delivered"] == frames["produced"] == len(gyros) > 900
    assert p.summary().triggers["imu"]["fallbacks"] == 0
    instants = set(p.board.emulators["imu"].measured_ns)
    assert all(g.t_ns in instants for g in gyros)


def test_at_1_percent_bus_errors_the_fifo_keeps_95_percent_and_accounts_for_every_frame(
        registry: Registry) -> None:
    """A failed transfer leaves the FIFO's frames in the chip for the next read; a failure
    the driver cannot resume from reconfigures it (its FIFO's frames lost, counted)."""
    p, gyros = _fly(registry, "fifo", 0.8 * DEPTH_NS / 1e9, bus_errors=0.01)
    frames = p.summary().frames["imu"]
    assert frames["delivered"] == len(gyros) >= 0.95 * _chip_count(p)
    assert frames["delivered"] + sum(v for k, v in frames.items() if k.startswith("lost_")) \
        == frames["produced"]
    chip = p.board.emulators["imu"]
    for g in gyros[::25]:
        i = bisect_right(chip.measured_ns, g.t_ns)
        instant = min(chip.measured_ns[max(i - 1, 0):i + 1], key=lambda t: abs(t - g.t_ns))
        assert abs(g.t_ns - instant) < 50_000
