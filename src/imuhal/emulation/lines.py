"""Emulated data-ready lines: a chip emulator's INT pin model driving a trigger line.

An :class:`EmulatedLine` stands for the GPIO line a profile's ``interrupt:`` names, on an
emulated board: its edges are the instants at which the chip's emulator asserts (and, for a
pulse, releases) its INT pin (:meth:`ChipEmulator.interrupt_after`), on the board's
simulated clock, numbered like the kernel numbers a line's edges. Like the kernel's, its
queue holds at most ``KERNEL_QUEUE`` edges: older ones are dropped (a gap in the numbers)
when the host does not read the line for longer.
"""

from __future__ import annotations

from imuhal.core.clock import Clock
from imuhal.pipeline.triggers import TriggerEdge
from imuhal.sim.chip import ChipEmulator

KERNEL_QUEUE = 16
"""The kernel's default queue of unread edge events per line (gpiolib-cdev)."""


class EmulatedLine:
    """The INT line of one emulated chip (see the module docstring)."""

    def __init__(self, name: str, emulator: ChipEmulator, clock: Clock, edge: str) -> None:
        self.name = name
        self.emulator = emulator
        self.clock = clock
        self.edge = edge
        self._last_ns = clock.now_ns()
        self._seqno = 0

    def next_edge_ns(self) -> int | None:
        """The next edge after the last one taken, as the chip is configured now."""
        emulator = self.emulator
        active_high, pulse_ns = emulator.interrupt_pin()
        leading = self.edge == "both" or (self.edge == "rising") == active_high
        trailing = pulse_ns > 0 and (self.edge == "both" or (self.edge == "rising")
                                     != active_high)
        found: list[int] = []
        if leading:
            t = emulator.interrupt_after(self._last_ns)
            if t is not None:
                found.append(t)
        if trailing:
            t = emulator.interrupt_after(self._last_ns - pulse_ns)
            if t is not None:
                found.append(t + pulse_ns)
        return min(found, default=None)

    def take_edges(self) -> list[TriggerEdge]:
        """The edges up to now; the newest ``KERNEL_QUEUE`` of them when more came."""
        now = self.clock.now_ns()
        edges: list[TriggerEdge] = []
        while (t := self.next_edge_ns()) is not None and t <= now:
            self._seqno += 1
            self._last_ns = t
            edges.append(TriggerEdge(t, self._seqno))
        return edges[-KERNEL_QUEUE:]

    def close(self) -> None:
        return None
