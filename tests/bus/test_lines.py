"""imuhal.bus.lines at the libgpiod v2 boundary with a stand-in module (the kernel's own
edges are in tests/kernel/test_gpio.py)."""

from __future__ import annotations

import enum
import time
from dataclasses import dataclass, field
from types import SimpleNamespace
from typing import Any

import pytest

from imuhal.bus.lines import DataReadyLine, Edge
from imuhal.core.errors import BusError


class _Type(enum.Enum):
    RISING_EDGE = 1
    FALLING_EDGE = 2


@dataclass
class _Event:
    event_type: _Type
    timestamp_ns: int
    line_seqno: int


@dataclass
class _Request:
    queued: list[_Event] = field(default_factory=list)
    fd: int = 7
    released: bool = False

    def wait_edge_events(self, timeout: float | None) -> bool:
        return bool(self.queued)

    def read_edge_events(self) -> list[_Event]:
        out, self.queued = self.queued, []
        return out

    def release(self) -> None:
        self.released = True


def _gpiod(request: _Request, fail: Exception | None = None) -> Any:
    line = SimpleNamespace(Edge=SimpleNamespace(RISING="r", FALLING="f", BOTH="b"),
                           Direction=SimpleNamespace(INPUT="in"),
                           Clock=SimpleNamespace(MONOTONIC="mono"))
    requested: dict[str, Any] = {}

    def request_lines(chip: str, **kwargs: Any) -> _Request:
        if fail is not None:
            raise fail
        requested.update(kwargs, chip=chip)
        return request

    return SimpleNamespace(line=line, LineSettings=lambda **kw: kw,
                           EdgeEvent=SimpleNamespace(Type=_Type), request_lines=request_lines,
                           requested=requested)


def test_edges_come_back_with_the_kernels_time_stamps_and_numbers() -> None:
    request = _Request([_Event(_Type.RISING_EDGE, 1_000, 1), _Event(_Type.FALLING_EDGE, 2_000, 2)])
    gpiod = _gpiod(request)
    with DataReadyLine("/dev/gpiochip0", "DRDY", edge="both", gpiod_module=gpiod) as line:
        assert line.fileno() == 7
        assert line.read_edges() == [Edge(1_000, 1, True), Edge(2_000, 2, False)]
        assert line.read_edges() == []
        assert line.lost_edges == 0
    settings = gpiod.requested["config"]["DRDY"]
    assert (settings["edge_detection"], settings["event_clock"]) == ("b", "mono")
    assert request.released


def test_a_gap_in_the_line_sequence_numbers_is_counted_as_lost_edges() -> None:
    request = _Request([_Event(_Type.RISING_EDGE, 1_000, 1), _Event(_Type.RISING_EDGE, 9_000, 5)])
    line = DataReadyLine("/dev/gpiochip0", 3, gpiod_module=_gpiod(request))
    assert [e.line_seqno for e in line.read_edges()] == [1, 5]
    assert line.lost_edges == 3


def test_a_line_that_cannot_be_requested_is_a_bus_error_naming_it() -> None:
    gpiod = _gpiod(_Request(), fail=OSError(16, "Device or resource busy"))
    with pytest.raises(BusError, match=r"line 'DRDY' of /dev/gpiochip0.*busy"):
        DataReadyLine("/dev/gpiochip0", "DRDY", gpiod_module=gpiod)


def test_a_trigger_line_hands_the_pipeline_kernel_stamps_on_its_own_clock() -> None:
    from imuhal.core.clock import MonotonicClock
    from imuhal.pipeline.board import GpioTriggerLine
    from imuhal.pipeline.triggers import TriggerEdge

    clock = MonotonicClock()
    now = time.monotonic_ns()
    request = _Request([_Event(_Type.RISING_EDGE, now, 1), _Event(_Type.RISING_EDGE, now + 5, 2)])
    line = GpioTriggerLine(DataReadyLine("/dev/gpiochip0", 17, gpiod_module=_gpiod(request)),
                           clock)
    stamp = clock.from_monotonic_ns(now)
    assert 0 <= stamp <= clock.now_ns()
    assert line.take_edges() == [TriggerEdge(stamp, 1), TriggerEdge(stamp + 5, 2)]
    assert (line.name, line.fileno()) == ("gpio:///dev/gpiochip0/17", 7)
    line.close()
    assert request.released
