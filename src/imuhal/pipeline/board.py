"""What the pipeline needs of a board, and the real one.

The pipeline sees a board only through :class:`Board`: its buses by profile name, the clock
that paces the poll loop and a hook run before each poll. A real board
(:func:`open_hardware_board`) opens the profile's buses through their bus plugins and runs on
the monotonic clock; an emulated one (:func:`imuhal.emulation.open_emulated`) supplies
emulated buses, a simulated clock, and hands each chip emulator its inputs before it is
polled. The pipeline cannot tell them apart, and knows nothing of simulation.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Protocol

from imuhal.bus.base import Bus
from imuhal.bus.lines import DataReadyLine
from imuhal.core.clock import Clock, MonotonicClock
from imuhal.pipeline.triggers import SelectorWaiter, TriggerEdge, Waiter
from imuhal.plugins.manager import Registry
from imuhal.profile.model import BoardProfile, InterruptConfig

LATE_AFTER_NS = 500_000
"""A real board's poll that comes more than 0.5 ms after its due time happens at the clock
(the host's thread was held); within it, the wake-up latency of a sleeping process, the poll
keeps its due time (a recording would otherwise hold a late poll for nearly every poll)."""


class Board(Protocol):
    """The board a pipeline polls. Optional attributes the pipeline reads when present:
    ``lines`` (data-ready lines by device), ``waiter`` and ``poll_plan`` (the drivers'
    poll plan, imuhal.core.poll_plan: a replayed recording's; else the newest)."""

    @property
    def buses(self) -> Mapping[str, Bus]:
        """The profile's buses by name (not the child buses chips provide)."""
        ...

    @property
    def clock(self) -> Clock:
        """The clock the pipeline sleeps on and timestamps with (int ns)."""
        ...

    def before_poll(self, t_ns: int, device: str) -> int:
        """Called at ``t_ns`` (the clock already there), just before ``device`` is polled.
        Returns the time the poll happens: ``t_ns``, or later when the host was late (the
        clock is past ``t_ns``: the one thread was held by another device's poll or
        recovery, or by a stall; an emulated board's injected late polls and jitter move
        the clock). A late poll is stamped when it happens, never at its old due time: the
        chips are read then (a recording keeps the time, so a replay polls at it)."""
        ...


class GpioTriggerLine:
    """A data-ready line on the GPIO character device (imuhal.bus.lines), its kernel edge
    time stamps (CLOCK_MONOTONIC) expressed on the pipeline's :class:`MonotonicClock`."""

    def __init__(self, line: DataReadyLine, clock: MonotonicClock) -> None:
        self.line = line
        self.name = line.name
        self._clock = clock

    def fileno(self) -> int:
        return self.line.fileno()

    def take_edges(self) -> list[TriggerEdge]:
        to_clock = self._clock.from_monotonic_ns
        return [TriggerEdge(to_clock(e.timestamp_ns), e.line_seqno)
                for e in self.line.read_edges(0.0)]

    def close(self) -> None:
        self.line.close()


def open_trigger_line(config: InterruptConfig, clock: MonotonicClock, *,
                      consumer: str = "imuhal") -> GpioTriggerLine:
    """Request the line ``config`` names for edge events (needs the ``gpio`` extra)."""
    return GpioTriggerLine(DataReadyLine(config.chip_path, config.line, edge=config.edge,
                                         consumer=consumer), clock)


@dataclass
class HardwareBoard:
    """A real board: the profile's buses, opened, on the monotonic clock, and the data-ready
    lines its devices' ``interrupt:`` name (by device)."""

    buses: dict[str, Bus]
    clock: Clock = field(default_factory=MonotonicClock)
    lines: dict[str, GpioTriggerLine] = field(default_factory=dict)

    def before_poll(self, t_ns: int, device: str) -> int:
        """Real chips measure the real world on their own: the poll is now. Up to
        LATE_AFTER_NS after ``t_ns`` (the operating system's wake-up latency) it keeps
        ``t_ns``, as an on-time poll; later, the one thread was held and the poll is at the
        clock (a recording keeps it as a late poll)."""
        now_ns = self.clock.now_ns()
        return now_ns if now_ns - t_ns > LATE_AFTER_NS else t_ns

    def waiter(self) -> Waiter:
        """One ``selectors`` wait over the lines and the next deadline."""
        return SelectorWaiter(self.clock, self.lines)


def open_hardware_board(profile: BoardProfile, registry: Registry) -> HardwareBoard:
    """Open every bus the profile names through its bus plugin, and every data-ready line
    its devices name; on failure those already opened are closed again."""
    clock = MonotonicClock()
    board = HardwareBoard({}, clock)
    try:
        for name, cfg in profile.buses.items():
            factory = registry.buses.get(cfg.kind)
            settings = factory.Settings.model_validate(cfg.plugin_settings())
            board.buses[name] = factory.open(name, settings)
        for name, dev in profile.devices.items():
            if dev.enabled and dev.interrupt is not None:
                board.lines[name] = open_trigger_line(dev.interrupt, clock,
                                                      consumer=f"imuhal:{name}")
    except BaseException:
        for bus in board.buses.values():
            bus.close()
        for line in board.lines.values():
            line.close()
        raise
    return board
