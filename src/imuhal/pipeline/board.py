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
from imuhal.core.clock import Clock, MonotonicClock
from imuhal.plugins.manager import Registry
from imuhal.profile.model import BoardProfile


class Board(Protocol):
    """The board a pipeline polls."""

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
        Returns the time the poll happens: ``t_ns``, or later when the host was late (an
        emulated board's injected late polls and jitter move the clock)."""
        ...


@dataclass
class HardwareBoard:
    """A real board: the profile's buses, opened, on the monotonic clock."""

    buses: dict[str, Bus]
    clock: Clock = field(default_factory=MonotonicClock)

    def before_poll(self, t_ns: int, device: str) -> int:
        """Nothing to do: real chips measure the real world on their own."""
        return t_ns


def open_hardware_board(profile: BoardProfile, registry: Registry) -> HardwareBoard:
    """Open every bus the profile names through its bus plugin; on failure the buses
    already opened are closed again."""
    buses: dict[str, Bus] = {}
    try:
        for name, cfg in profile.buses.items():
            factory = registry.buses.get(cfg.kind)
            settings = factory.Settings.model_validate(cfg.plugin_settings())
            buses[name] = factory.open(name, settings)
    except BaseException:
        for bus in buses.values():
            bus.close()
        raise
    return HardwareBoard(buses)
