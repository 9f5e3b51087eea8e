"""Data-ready lines on the kernel's gpio-sim chip, read through imuhal.bus.lines (gpiod v2).

gpio-sim raises an edge when its line's pull is switched (sysfs ``pull``), from the
simulated interrupt's work: edges faster than the guest handles them merge into one. So each
edge is handshaken (pull up, wait for the event, pull down) and nothing here bounds latency
(under emulation it says nothing about hardware): the tests check counts, sequence numbers,
and that the time stamps are the kernel's CLOCK_MONOTONIC.
"""

from __future__ import annotations

import itertools
import select
import time
import uuid
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import pytest
from tests.kernel.guest import mounted_configfs, wait_for

from imuhal.bus.lines import DataReadyLine

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
