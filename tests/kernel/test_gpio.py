"""Data-ready lines on the kernel's gpio-sim chip, read through imuhal.bus.lines (gpiod v2),
and driving the pipeline's acquisition trigger (imuhal.pipeline.triggers).

gpio-sim raises an edge when its line's pull is switched (sysfs ``pull``), from the
simulated interrupt's work: edges faster than the guest handles them merge into one. So each
edge is handshaken (pull up, wait for the event, pull down) and nothing here bounds latency
(under emulation it says nothing about hardware): the tests check counts, sequence numbers,
and that the time stamps are the kernel's CLOCK_MONOTONIC. The trigger tests read an
emulated MPU-9250 (register level, on the real monotonic clock) whenever the gpio-sim line
says so, through the same board a real run opens (HardwareBoard, a selectors wait).
"""

from __future__ import annotations

import itertools
import select
import threading
import time
import uuid
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path

import pytest
from tests.kernel.guest import mounted_configfs, wait_for

from imuhal.bus.base import BusKind
from imuhal.bus.lines import DataReadyLine
from imuhal.core.clock import MonotonicClock
from imuhal.core.samples import GyroSample
from imuhal.emulation import EmulatedBus
from imuhal.pipeline import Pipeline
from imuhal.pipeline.board import HardwareBoard, open_trigger_line
from imuhal.pipeline.triggers import LineTrigger
from imuhal.plugins.manager import load_registry
from imuhal.profile.loader import parse_profile
from imuhal.sinks import Event
from imuhal_chips.mpu9250.emulator import MPU9250Emulator

EDGES = 1000


@dataclass(frozen=True)
class SimLine:
    chip: str
    """/dev/gpiochipN"""
    pull: Path
    """The sysfs file that drives the simulated input."""

    def set(self, high: bool) -> None:
        self.pull.write_text("pull-up" if high else "pull-down")


@pytest.fixture
def sim_line() -> Iterator[SimLine]:
    """One gpio-sim chip with a line named DRDY, created in configfs and removed after."""
    root = mounted_configfs() / "gpio-sim"
    if not root.is_dir():
        pytest.skip("kernel test: the kernel has no gpio-sim (CONFIG_GPIO_SIM)")
    device = root / f"imuhal-{uuid.uuid4().hex[:8]}"
    line = device / "bank0" / "line0"
    line.mkdir(parents=True)
    (device / "bank0" / "num_lines").write_text("1")
    (device / "bank0" / "label").write_text("imuhal-drdy")
    (line / "name").write_text("DRDY")
    (device / "live").write_text("1")
    try:
        dev_name = (device / "dev_name").read_text().strip()
        chip_name = (device / "bank0" / "chip_name").read_text().strip()
        pull = wait_for(Path(f"/sys/devices/platform/{dev_name}/{chip_name}/sim_gpio0/pull"))
        yield SimLine(str(wait_for(Path(f"/dev/{chip_name}"))), pull)
    finally:
        (device / "live").write_text("0")
        line.rmdir()
        (device / "bank0").rmdir()
        device.rmdir()


def test_a_thousand_handshaken_edges_arrive_with_contiguous_sequence_numbers(
        sim_line: SimLine) -> None:
    sim_line.set(False)
    seen = []
    with DataReadyLine(sim_line.chip, "DRDY", edge="rising") as drdy:
        for _ in range(EDGES):
            before_ns = time.monotonic_ns()
            sim_line.set(True)
            edges = drdy.read_edges(timeout_s=10.0)
            after_ns = time.monotonic_ns()
            sim_line.set(False)
            assert len(edges) == 1 and edges[0].rising
            # the kernel's CLOCK_MONOTONIC: between the pull write and the read
            assert before_ns <= edges[0].timestamp_ns <= after_ns
            seen.append(edges[0])
        assert drdy.lost_edges == 0
        assert drdy.read_edges(timeout_s=0.05) == []  # falling edges are not events
    assert [e.line_seqno for e in seen] == list(range(1, EDGES + 1))
    stamps = [e.timestamp_ns for e in seen]
    assert all(b > a for a, b in itertools.pairwise(stamps))


def test_the_line_is_a_file_descriptor_readable_only_while_edges_are_queued(
        sim_line: SimLine) -> None:
    sim_line.set(False)
    with DataReadyLine(sim_line.chip, 0, edge="both") as drdy:
        assert select.select([drdy], [], [], 0.05)[0] == []
        sim_line.set(True)
        assert select.select([drdy], [], [], 10.0)[0] == [drdy]
        assert [e.rising for e in drdy.read_edges()] == [True]
        assert select.select([drdy], [], [], 0.05)[0] == []


def test_edges_a_full_kernel_queue_dropped_are_counted_as_lost(sim_line: SimLine) -> None:
    sim_line.set(False)
    with DataReadyLine(sim_line.chip, "DRDY", edge="rising", event_buffer_size=16) as drdy:
        for _ in range(40):  # unread: the queue of 16 fills
            sim_line.set(True)
            time.sleep(0.005)
            sim_line.set(False)
            time.sleep(0.005)
        queued = drdy.read_edges(timeout_s=5.0)
        sim_line.set(True)
        last = drdy.read_edges(timeout_s=10.0)[-1]
    assert len(queued) == 16
    # every edge the kernel numbered is either read or counted lost
    assert drdy.lost_edges == last.line_seqno - len(queued) - 1 > 0


PROFILE = """
schema_version: 1
name: drdy-guest
buses:
  i2c1: {{kind: i2c, device: /dev/i2c-1}}
devices:
  imu:
    driver: mpu9250
    bus: i2c1
    address: 0x68
    interrupt: {{chip: {chip}, line: DRDY, edge: rising, watchdog_periods: {watchdog}}}
    settings: {{odr_hz: 200, aux: "off"}}
"""


def _pipeline(line: SimLine, watchdog_periods: float) -> tuple[Pipeline, LineTrigger]:
    """An emulated MPU-9250 at 200 Hz on the monotonic clock, its INT wired to the gpio-sim
    line: the board a real run opens, with an emulated bus in place of /dev/i2c-1."""
    registry = load_registry()
    profile = parse_profile(PROFILE.format(chip=line.chip, watchdog=watchdog_periods),
                            "guest profile", registry)
    clock = MonotonicClock()
    bus = EmulatedBus("emul://i2c1", BusKind.I2C)
    bus.attach(0x68, MPU9250Emulator(clock))
    interrupt = profile.devices["imu"].interrupt
    assert interrupt is not None
    board = HardwareBoard({"i2c1": bus}, clock, {"imu": open_trigger_line(interrupt, clock)})
    pipeline = Pipeline(profile, registry, board, calibrated=False)
    trigger = pipeline.devices["imu"].trigger
    assert isinstance(trigger, LineTrigger)
    return pipeline, trigger


def _await(check: Callable[[], bool], timeout_s: float = 10.0) -> None:
    deadline = time.monotonic() + timeout_s
    while not check():
        if time.monotonic() > deadline:
            raise AssertionError("the pipeline did not read the line within 10 s")
        time.sleep(0.0002)


def test_every_handshaken_edge_makes_one_read_stamped_with_the_kernels_time(
        sim_line: SimLine) -> None:
    sim_line.set(False)
    # a watchdog of 100,000 periods (500 s) never fires here: every read is the line's
    pipeline, trigger = _pipeline(sim_line, watchdog_periods=100_000)
    events: list[Event] = []
    stop = threading.Event()

    def consume() -> None:
        for event in pipeline.events(None):
            events.append(event)
            # only the final edge's read ends the run: an event of the last handshake handed
            # out after `stop` must not (the final edge then went unread: 1,000 reads of 1,001)
            if stop.is_set() and trigger.reads > EDGES:
                return

    consumer = threading.Thread(target=consume, daemon=True)
    with pipeline:
        consumer.start()
        starts = []
        edges_ns = []  # the kernel's stamp of each handshake's edge, as the trigger took it
        for i in range(EDGES):
            starts.append(time.monotonic_ns())
            sim_line.set(True)
            _await(lambda n=i + 1: trigger.reads >= n)
            edges_ns.append(trigger.taken_ns[-1])
            sim_line.set(False)
            assert trigger.reads == i + 1  # one read per edge, none extra
        stop.set()
        time.sleep(0.02)  # the chip has a new sample for the last read, which ends the run
        sim_line.set(True)
        consumer.join(timeout=10.0)
        assert not consumer.is_alive()
    assert trigger.edges == trigger.reads == EDGES + 1
    assert trigger.lost_edges == trigger.overwritten == trigger.fallbacks == 0
    assert pipeline.warnings == []
    # each sample carries its edge's kernel time stamp, and each edge's stamp is the
    # kernel's CLOCK_MONOTONIC: after its handshake's pull-up, before the next one's. (Not
    # bounded by when the handshake saw its read: gpio-sim raises the interrupt from an
    # irq_work, where the kernel stamps the edge, and on a loaded TCG guest that work ran
    # once 0.96 ms after the host had written the pull and seen a read; CI, session 19.)
    # the clock's own origin, not monotonic_ns() - now_ns(): read apart, a preemption
    # between the two reads (223 us on a loaded TCG guest, CI, session 24) put every edge
    # that far early
    origin = -pipeline.clock.from_monotonic_ns(0)
    stamps = [e.t_ns for e in events if isinstance(e, GyroSample)]
    assert len(stamps) > EDGES // 10  # the chip had new data for many of the reads
    assert all(b > a for a, b in itertools.pairwise(stamps))
    assert set(stamps[:-1]) <= set(edges_ns)
    assert all(b > a for a, b in itertools.pairwise(edges_ns))
    for i, edge_ns in enumerate(edges_ns):
        t = edge_ns + origin
        assert starts[i] <= t and (i + 1 == EDGES or t < starts[i + 1])


def test_a_silent_line_falls_back_to_polling_says_so_once_and_returns_on_an_edge(
        sim_line: SimLine) -> None:
    sim_line.set(False)
    pipeline, trigger = _pipeline(sim_line, watchdog_periods=4)  # 20 ms at 200 Hz
    with pipeline:
        polled = [e for e in pipeline.events(0.5) if isinstance(e, GyroSample)]
        assert trigger.reads == 0 and trigger.fallbacks == 1
        assert trigger.fallback_polls > 0 and any(s.valid for s in polled)
        sim_line.set(True)  # the line comes back: read on it, then silent again
        list(pipeline.events(0.3))
    assert trigger.reads == trigger.edges == trigger.returns == 1
    assert trigger.fallbacks == 2
    silent = [w for w in pipeline.warnings if "no data-ready edge" in w]
    assert len(silent) == 1 and silent[0].startswith(
        f"imu: no data-ready edge on gpio://{sim_line.chip}/DRDY for 20 ms (4 periods)")
