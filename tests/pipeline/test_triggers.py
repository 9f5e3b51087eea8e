"""Triggers: a device read on its chip's data-ready line (emulated INT pin), the watchdog's
fallback to polling, and the profile's ``interrupt:`` entry."""

from __future__ import annotations

import itertools
import os
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from imuhal.core.clock import MonotonicClock
from imuhal.core.errors import PluginError
from imuhal.core.samples import GyroSample, Sample
from imuhal.emulation import open_emulated
from imuhal.emulation.board import EmulatedBoard
from imuhal.pipeline.pipeline import RunSummary
from imuhal.pipeline.triggers import LineTrigger, SelectorWaiter, TriggerEdge
from imuhal.plugins.manager import Registry, load_registry
from imuhal.profile.bundled import bundled_profiles
from imuhal.profile.faults import ChipAbsent, ChipReset, HostStall
from imuhal.profile.loader import check_profile, load_profile
from imuhal.profile.model import BoardProfile
from imuhal.sinks import CallbackSink, Event

GY91 = bundled_profiles()["gy91.yaml"]
INTERRUPT = "    interrupt: {chip: gpiochip0, line: 17, edge: rising}\n"


@pytest.fixture(scope="module")
def registry() -> Registry:
    return load_registry()


def gy91_text(interrupt: str = INTERRUPT, device_mount: str = '    mount: "+X-Y-Z"\n') -> str:
    """The GY-91 profile with ``interrupt`` added to its MPU-9250 (``imu``)."""
    text = GY91.read_text()
    assert device_mount in text
    return text.replace(device_mount, device_mount + interrupt, 1)


@pytest.fixture
def gy91_line(tmp_path: Path, registry: Registry) -> BoardProfile:
    path = tmp_path / "gy91-int.yaml"
    path.write_text(gy91_text())
    return load_profile(path, registry)


def _run(profile: BoardProfile, registry: Registry, seconds: float, **kw: Any
         ) -> tuple[list[Event], EmulatedBoard, RunSummary]:
    events: list[Event] = []
    with open_emulated(profile, registry, scenario="thermal", seed=3, **kw) as pipeline:
        summary = pipeline.run(seconds, [CallbackSink(events.append)])
        board = EmulatedBoard.of(pipeline)
    return events, board, summary


def _imu_stamps(events: list[Event]) -> list[int]:
    return [e.t_ns for e in events if isinstance(e, GyroSample) and e.device == "imu"]


def test_a_data_ready_line_reads_the_chip_once_per_edge_stamped_at_the_chips_instant(
        gy91_line: BoardProfile, registry: Registry) -> None:
    # raw samples: the gyro offset phase at start-up would keep the first 0.5 s
    events, board, summary = _run(gy91_line, registry, 3.0, calibrated=False)
    stamps = _imu_stamps(events)
    measured = set(board.emulators["imu"].measured_ns)
    counts = summary.triggers["imu"]
    assert len(stamps) == counts["reads"] == counts["edges"] == 600
    assert set(stamps) <= measured  # every stamp is an instant the chip measured
    assert counts["fallbacks"] == counts["overwritten"] == counts["lost_edges"] == 0
    assert summary.warnings == []


def test_devices_without_interrupt_keep_the_timer_trigger(
        gy91_line: BoardProfile, registry: Registry) -> None:
    _, _, summary = _run(gy91_line, registry, 0.5)
    assert set(summary.triggers) == {"imu"}


def test_a_silent_line_falls_back_to_polling_says_so_once_and_returns_to_the_line(
        gy91_line: BoardProfile, registry: Registry) -> None:
    # a chip reset clears INT_ENABLE: the chip keeps sampling, its INT pin goes silent, the
    # driver's reset check (on the watchdog's polls) programs it again and the edges return
    resets = [ChipReset(device="imu", start_s=t) for t in (1.0, 2.0)]
    events, _, summary = _run(gy91_line, registry, 3.0, faults=resets)
    counts = summary.triggers["imu"]
    assert counts["fallbacks"] == counts["returns"] == 2
    assert counts["fallback_polls"] > 0
    silent = [w for w in summary.warnings if "no data-ready edge" in w]
    assert silent == ["imu: no data-ready edge on emul://imu/INT for 20 ms (4 periods): "
                      "polling the chip instead until the line's edges come back"]
    stamps = _imu_stamps(events)
    assert stamps[-1] > 2.9e9  # the device was read to the end


def test_a_stalled_host_reads_the_newest_sample_with_the_newest_edges_stamp(
        gy91_line: BoardProfile, registry: Registry) -> None:
    stall = HostStall(device="imu", start_s=1.0, stall_s=0.05, every_s=0.5)
    events, board, summary = _run(gy91_line, registry, 3.0, faults=[stall])
    counts = summary.triggers["imu"]
    frames = summary.frames["imu"]
    assert set(_imu_stamps(events)) <= set(board.emulators["imu"].measured_ns)
    # each 50 ms stall at 200 Hz: of the 11 edges from the stalled read's to the wake,
    # the newest is read and 10 frames are overwritten
    stalls = board.faults.log.injected["imu"]["host_stall"]
    assert stalls >= 4
    assert counts["overwritten"] == frames["lost_host_stall"] == 10 * stalls
    assert frames["delivered"] + frames["lost_host_stall"] == frames["produced"]


def test_a_line_recorded_is_replayed_to_the_same_floats(
        tmp_path: Path, registry: Registry) -> None:
    from imuhal.bus.recording.format import RecordedEdge, open_recording
    from imuhal.bus.recording.recorder import BusRecorder, run_header
    from imuhal.offline.replay import open_replay, replay_pipeline, replay_run

    path = tmp_path / "gy91-int.yaml"
    path.write_text(gy91_text())
    out = tmp_path / "run.imurec"
    recorder = BusRecorder(out, run_header(path.read_text(), str(path), emulate="thermal",
                                           seed=3))
    stall = HostStall(device="imu", start_s=0.5, stall_s=0.03, every_s=0.5)
    live, _, _ = _run(load_profile(path, registry), registry, 2.0, recorder=recorder,
                      faults=[stall])
    recorder.close()
    edges = [r for r in open_recording(out).records() if isinstance(r, RecordedEdge)]
    assert [e.seqno for e in edges] == list(range(1, len(edges) + 1))
    replayed: list[Event] = []
    replay_run(replay_pipeline(open_replay(out, registry), registry),
               [CallbackSink(replayed.append)])
    assert [repr(e) for e in replayed] == [repr(e) for e in live]


def test_a_chip_whose_emulator_has_no_int_pin_cannot_have_its_line_emulated(
        tmp_path: Path, registry: Registry) -> None:
    path = tmp_path / "baro-int.yaml"
    path.write_text(gy91_text(device_mount="    address: 0x76\n"))
    with pytest.raises(PluginError, match=r"^devices\.baro\.interrupt: the bmp280 emulator "
                       r"models no INT pin.*remove interrupt:"):
        open_emulated(load_profile(path, registry), registry)


@pytest.mark.parametrize(("entry", "problem"), [
    ("{chip: gpio0, line: 17}", "devices.imu.interrupt.chip: not a GPIO character device: "
                                "give gpiochipN or /dev/gpiochipN (list them with gpiodetect)"),
    ("{chip: gpiochip0, line: -1}", "devices.imu.interrupt.line: a line offset is 0 or more: "
                                    "give the offset gpioinfo lists"),
    ("{chip: gpiochip0, line: 17, edge: up}", "devices.imu.interrupt.edge: Input should be "
                                              "'rising', 'falling' or 'both'"),
    ("{chip: gpiochip0, line: 17, watchdog_periods: 1}",
     "devices.imu.interrupt.watchdog_periods: Input should be greater than or equal to 1.5"),
    ("{chip: gpiochip0}", "devices.imu.interrupt.line: required key is missing; add it"),
])
def test_a_wrong_interrupt_entry_is_one_line_naming_the_field(
        tmp_path: Path, registry: Registry, entry: str, problem: str) -> None:
    path = tmp_path / "bad.yaml"
    path.write_text(gy91_text(f"    interrupt: {entry}\n"))
    problems = check_profile(path, registry)
    assert len(problems) == 1 and problem in problems[0] and "\n" not in problems[0]


class PipeLine:
    """A selectable line over a pipe: each byte written is one edge."""

    def __init__(self) -> None:
        self.read_fd, self.write_fd = os.pipe()
        os.set_blocking(self.read_fd, False)
        self.name = "pipe"
        self.takes = 0
        self.seqno = 0

    def fileno(self) -> int:
        return self.read_fd

    def edge(self) -> None:
        os.write(self.write_fd, b"e")

    def take_edges(self) -> list[TriggerEdge]:
        self.takes += 1
        try:
            got = os.read(self.read_fd, 64)
        except BlockingIOError:
            got = b""
        edges = []
        for _ in got:
            self.seqno += 1
            edges.append(TriggerEdge(time.monotonic_ns(), self.seqno))
        return edges

    def close(self) -> None:
        os.close(self.read_fd)
        os.close(self.write_fd)


@pytest.fixture
def pipe_line() -> Iterator[PipeLine]:
    line = PipeLine()
    yield line
    line.close()


def test_the_selector_waits_for_the_deadline_without_polling_a_silent_line(
        pipe_line: PipeLine) -> None:
    clock = MonotonicClock()
    waiter = SelectorWaiter(clock, {"imu": pipe_line})
    deadline = clock.now_ns() + 30_000_000
    assert waiter.wait(deadline) == {}
    assert clock.now_ns() >= deadline
    assert pipe_line.takes == 0  # the line was never read: one select, no busy poll


def test_the_selector_returns_a_lines_edges_before_the_deadline(pipe_line: PipeLine) -> None:
    clock = MonotonicClock()
    waiter = SelectorWaiter(clock, {"imu": pipe_line})
    pipe_line.edge()
    pipe_line.edge()
    woke = waiter.wait(clock.now_ns() + 10_000_000_000)
    assert [e.seqno for e in woke["imu"]] == [1, 2]
    assert waiter.take("imu") == []


def test_a_sample_is_never_stamped_before_the_previous_one_on_a_line(
        gy91_line: BoardProfile, registry: Registry) -> None:
    stall = HostStall(device="baro", start_s=0.2, stall_s=0.02, rate_hz=5.0)
    events, _, _ = _run(gy91_line, registry, 2.0, faults=[stall])
    stamps = [e.t_ns for e in events if isinstance(e, Sample) and e.device == "imu"]
    assert all(b >= a for a, b in itertools.pairwise(stamps))


def _gy91_fifo(tmp_path: Path, registry: Registry, interrupt: str) -> BoardProfile:
    path = tmp_path / "gy91-fifo.yaml"
    text = gy91_text(interrupt)
    path.write_text(text.replace("      aux: bypass\n", "      aux: bypass\n      read: fifo\n"))
    return load_profile(path, registry)


def test_a_fifo_read_on_every_second_edge_keeps_every_frame_through_stalls(
        tmp_path: Path, registry: Registry) -> None:
    profile = _gy91_fifo(tmp_path, registry,
                         "    interrupt: {chip: gpiochip0, line: 17, edges_per_read: 2}\n")
    stall = HostStall(device="imu", start_s=1.0, stall_s=0.05, every_s=0.5)
    events, board, summary = _run(profile, registry, 3.0, faults=[stall], calibrated=False)
    counts = summary.triggers["imu"]
    frames = summary.frames["imu"]
    measured = board.emulators["imu"].measured_ns
    assert frames["delivered"] == frames["produced"] == len(measured) == 600
    assert counts["reads"] < counts["edges"] // 2 + 1
    assert counts["edges"] == frames["produced"] and counts["fallbacks"] == 0
    # each frame stamped with its own edge: the chip's instant, whatever the stalls
    assert _imu_stamps(events) == list(measured)


def test_fifo_frames_held_for_their_stamps_when_the_run_ends_are_delivered(
        tmp_path: Path, registry: Registry) -> None:
    # without a line, frames wait until the read-time estimate of the chip's clock places
    # them (imuhal_chips.mpu9250.fifo), about 0.35 s into the flight: a 0.2 s run ends
    # with every frame read still held, and its end hands them out stamped as the
    # estimate stands
    profile = _gy91_fifo(tmp_path, registry, "")
    events, board, summary = _run(profile, registry, 0.2, calibrated=False)
    frames = summary.frames["imu"]
    stamps = _imu_stamps(events)
    measured = list(board.emulators["imu"].measured_ns)
    assert frames["delivered"] == len(stamps) == frames["produced"] == len(measured) > 30
    assert max(abs(a - b) for a, b in zip(stamps, measured, strict=True)) < 50_000


def test_an_optional_device_that_joins_late_awaits_its_first_edge_from_then(
        tmp_path: Path, registry: Registry) -> None:
    path = tmp_path / "late.yaml"
    text = gy91_text(INTERRUPT + "    required: false\n")
    path.write_text(text.replace("    address: 0x0C\n", "    address: 0x0C\n    required: false\n"))
    unplugged = ChipAbsent(device="imu", start_s=0.0, end_s=1.2)
    _, _, summary = _run(load_profile(path, registry), registry, 3.0, faults=[unplugged],
                         calibrated=False)
    counts = summary.triggers["imu"]
    assert "imu: found at t=2.000 s; it joins the run" in summary.warnings
    assert counts["fallbacks"] == 0 and counts["edges"] == counts["reads"] > 150


def test_edges_the_kernel_did_not_queue_are_filled_in_evenly_for_the_driver() -> None:
    trigger = LineTrigger("emul://imu/INT", 5_000_000, 4.0)
    trigger.took([TriggerEdge(1_000, 1)])
    assert trigger.taken_ns == [1_000]
    trigger.took([TriggerEdge(15_001_000, 4)])  # edges 2 and 3 never reached the queue
    assert trigger.taken_ns == [5_001_000, 10_001_000, 15_001_000]
    assert trigger.lost_edges == 2
