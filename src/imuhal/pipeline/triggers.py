"""Triggers: what tells the pipeline to read a device, and the one place it waits.

Two triggers (docs/acquisition.md, "Triggers"):

* :class:`TimerTrigger` (a device without ``interrupt:`` in its profile): the device is read
  when its driver's poll grid says (``PollResult.next_poll_ns``), as imuhal always did.
* :class:`LineTrigger` (``interrupt: {chip: gpiochip0, line: 17, edge: rising}``): the
  device is read when its chip's INT pin raises an edge on a GPIO line, and its samples are
  stamped with the edge's time (the kernel's time stamp of the interrupt, on the pipeline's
  clock). A watchdog falls back to the poll grid when the line stays silent for
  ``watchdog_periods`` of the chip's output periods, says so once, and returns to the line
  when its edges come back. Edges the host did not read before a newer one came (a stalled
  host) are counted ``overwritten``: a data-ready chip keeps one sample; the read gets the
  newest and is stamped with the newest edge.

The pipeline waits through a :class:`Waiter`: until the next deadline of its schedule or an
edge on any line, whichever comes first. On hardware (:class:`SelectorWaiter`) that is one
``selectors`` call over the lines' file descriptors with the deadline as its timeout, never a
busy poll; an emulated board's lines are driven by its chips' INT pin models on the simulated
clock (:class:`SimulatedWaiter`); a replay's come from the recording.
"""

from __future__ import annotations

import selectors
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Protocol

from imuhal.core.clock import Clock


@dataclass(frozen=True, slots=True)
class TriggerEdge:
    """One edge of a trigger line, on the pipeline's clock."""

    t_ns: int
    """When the edge happened (ns, the pipeline clock): on hardware the kernel's time stamp
    of the interrupt, on an emulated board the instant the chip's INT pin switched."""
    seqno: int
    """The edge's number on its line since the line was opened (1 for the first); a gap
    is edges the kernel could not queue."""


class TriggerLine(Protocol):
    """A line the pipeline waits on: the edges queued since the last take."""

    name: str

    def take_edges(self) -> list[TriggerEdge]:
        """The edges queued now, oldest first (without waiting); empty when none."""
        ...

    def close(self) -> None:
        """Release the line."""
        ...


class Waiter(Protocol):
    """Where the pipeline waits: until ``deadline_ns`` or an edge, whichever is first."""

    def wait(self, deadline_ns: int) -> dict[str, list[TriggerEdge]]:
        """Wait until the clock reads ``deadline_ns`` or some line has edges queued; the
        edges taken, by device (empty: the deadline came first)."""
        ...

    def take(self, device: str) -> list[TriggerEdge]:
        """The edges of ``device``'s line queued now (after a late read: those that came
        while the host was away)."""
        ...


class ClockWaiter:
    """No lines: wait on the clock alone (every device on the timer trigger)."""

    def __init__(self, clock: Clock) -> None:
        self.clock = clock

    def wait(self, deadline_ns: int) -> dict[str, list[TriggerEdge]]:
        self.clock.sleep_until(deadline_ns)
        return {}

    def take(self, device: str) -> list[TriggerEdge]:
        return []


class SelectableLine(TriggerLine, Protocol):
    def fileno(self) -> int:
        """A file descriptor readable while edges are queued."""
        ...


class SelectorWaiter:
    """Real lines: one ``selectors`` wait over every line's file descriptor, its timeout
    the time left to the deadline on ``clock`` (the unrecorded board clock: how long the
    host waited is not part of a recording, which edges came is)."""

    def __init__(self, clock: Clock, lines: Mapping[str, SelectableLine]) -> None:
        self.clock = clock
        self.lines = dict(lines)
        self._selector = selectors.DefaultSelector()
        for device, line in self.lines.items():
            self._selector.register(line, selectors.EVENT_READ, device)

    def wait(self, deadline_ns: int) -> dict[str, list[TriggerEdge]]:
        while True:
            left_ns = deadline_ns - self.clock.now_ns()
            ready = self._selector.select(max(0.0, left_ns / 1e9))
            taken = {key.data: edges for key, _ in ready
                     if (edges := self.lines[key.data].take_edges())}
            if taken or left_ns <= 0:
                return taken
            if not ready:  # the timeout ran out (select may return a little early)
                self.clock.sleep_until(deadline_ns)
                return {}

    def take(self, device: str) -> list[TriggerEdge]:
        return self.lines[device].take_edges()

    def close(self) -> None:
        self._selector.close()


class SimulatedLine(TriggerLine, Protocol):
    def next_edge_ns(self) -> int | None:
        """When the line's next edge not yet taken happens (pipeline clock), as its source
        is configured now; None: no edge will come unless something changes."""
        ...


class SimulatedWaiter:
    """Emulated lines on a simulated clock: the clock moves to the earliest edge due before
    the deadline (the edge's instant), or to the deadline."""

    def __init__(self, clock: Clock, lines: Mapping[str, SimulatedLine]) -> None:
        self.clock = clock
        self.lines = dict(lines)

    def wait(self, deadline_ns: int) -> dict[str, list[TriggerEdge]]:
        first: int | None = None
        for line in self.lines.values():
            t = line.next_edge_ns()
            if t is not None and t <= deadline_ns and (first is None or t < first):
                first = t
        if first is None:
            self.clock.sleep_until(deadline_ns)
            return {}
        self.clock.sleep_until(first)
        return {device: edges for device, line in self.lines.items()
                if (edges := line.take_edges())}

    def take(self, device: str) -> list[TriggerEdge]:
        return self.lines[device].take_edges()


class RecordedWaiter:
    """A waiter whose edges are written to a recording as they are taken (``record(device,
    edge)``), so a replay hands the pipeline the same edges at the same points."""

    def __init__(self, inner: Waiter, record: Callable[[str, TriggerEdge], None]) -> None:
        self.inner = inner
        self._record = record

    def wait(self, deadline_ns: int) -> dict[str, list[TriggerEdge]]:
        taken = self.inner.wait(deadline_ns)
        for device, edges in taken.items():
            for edge in edges:
                self._record(device, edge)
        return taken

    def take(self, device: str) -> list[TriggerEdge]:
        edges = self.inner.take(device)
        for edge in edges:
            self._record(device, edge)
        return edges


class TimerTrigger:
    """The device is read when its driver's poll grid says: today's behaviour."""

    mode = "timer"

    def due(self, t_ns: int, driver_next_ns: int) -> int:
        """When to read the device next after a read at ``t_ns``: the driver's choice."""
        return driver_next_ns

    def counts(self) -> dict[str, int]:
        return {}


class LineTrigger:
    """A data-ready line: read on its edges, polled on the driver's grid while it is silent
    (see the module docstring)."""

    mode = "data-ready"

    def __init__(self, line: str, period_ns: int, watchdog_periods: float,
                 edges_per_read: int = 1) -> None:
        self.line = line
        self.edges_per_read = edges_per_read
        """Edges counted to one read (a watermark: a chip reading its FIFO in bursts)."""
        self._pending = 0
        """The line's name (``gpio:///dev/gpiochip0/17``, ``emul://imu/INT``)."""
        self.period_ns = period_ns
        self.watchdog_periods = watchdog_periods
        self.on_line = True
        """False while the watchdog has the device polled (the line went silent)."""
        self.watchdog_at_ns = 0
        """When the watchdog fires unless an edge comes first."""
        self._last_seqno = 0
        self._last_edge_ns: int | None = None
        self.taken_ns: list[int] = []
        """The instants of the edges of the latest take, oldest first, with those the kernel
        numbered but did not queue filled in evenly between their neighbours: one per
        sample the chip produced (what a driver stamps buffered frames with)."""
        self.edges = 0
        """Edges taken from the line."""
        self.reads = 0
        """Reads the line triggered (one per wake, with the newest edge's time)."""
        self.overwritten = 0
        """Edges beyond ``edges_per_read`` at a read (the host came late): a chip that
        keeps one sample overwrote theirs; a FIFO keeps them."""
        self.lost_edges = 0
        """Edges the kernel numbered but did not queue (its event queue was full)."""
        self.fallbacks = 0
        """Times the watchdog fell back to polling."""
        self.fallback_polls = 0
        """Polls made while falling back."""
        self.returns = 0
        """Times the line's edges came back after a fallback."""

    @property
    def watchdog_ns(self) -> int:
        """How long the line may stay silent (ns): ``watchdog_periods`` chip periods, and
        at least the span of the edges counted to one read."""
        periods = max(self.watchdog_periods, self.edges_per_read + 1.5)
        return max(1, round(periods * self.period_ns))

    def started(self, t_ns: int) -> int:
        """The device starts at ``t_ns``: the first edge is awaited until the watchdog."""
        self.watchdog_at_ns = t_ns + self.watchdog_ns
        return self.watchdog_at_ns

    def took(self, edges: list[TriggerEdge]) -> TriggerEdge | None:
        """Count ``edges`` (oldest first, at least one); returns the newest when they make
        a read (``edges_per_read`` reached: the read's samples carry its time), else None.
        Edges bring a fallen-back line back and restart the watchdog."""
        self.taken_ns = []
        for edge in edges:
            missing = max(0, edge.seqno - self._last_seqno - 1)
            self.lost_edges += missing
            if missing and self._last_edge_ns is not None:
                step = (edge.t_ns - self._last_edge_ns) / (missing + 1)
                self.taken_ns += [round(self._last_edge_ns + (i + 1) * step)
                                  for i in range(missing)]
            self.taken_ns.append(edge.t_ns)
            self._last_seqno = edge.seqno
            self._last_edge_ns = edge.t_ns
        self.edges += len(edges)
        if not self.on_line:
            self.on_line = True
            self.returns += 1
        newest = edges[-1]
        self.watchdog_at_ns = newest.t_ns + self.watchdog_ns
        self._pending += len(edges)
        if self._pending < self.edges_per_read:
            return None
        self.overwritten += self._pending - self.edges_per_read
        self._pending = 0
        self.reads += 1
        return newest

    def expired(self, t_ns: int) -> bool:
        """True when a read due at ``t_ns`` is the watchdog firing (the line was silent for
        its whole span): the trigger falls back to polling, counted."""
        if not self.on_line or t_ns < self.watchdog_at_ns:
            return False
        self.on_line = False
        self.fallbacks += 1
        return True

    def due(self, t_ns: int, driver_next_ns: int) -> int:
        """After a read at ``t_ns``: on the line, the watchdog's deadline; fallen back, the
        driver's poll grid."""
        if self.on_line:
            return self.watchdog_at_ns
        self.fallback_polls += 1
        return driver_next_ns

    def counts(self) -> dict[str, int]:
        return {"edges": self.edges, "reads": self.reads, "overwritten": self.overwritten,
                "lost_edges": self.lost_edges, "fallbacks": self.fallbacks,
                "fallback_polls": self.fallback_polls, "returns": self.returns}

    def describe_silence(self) -> str:
        """The watchdog's warning, once per device."""
        return (f"no data-ready edge on {self.line} for {self.watchdog_ns / 1e6:g} ms "
                f"({self.watchdog_ns / self.period_ns:g} periods): polling the chip instead "
                "until the line's edges come back")


def describe_trigger(counts: Mapping[str, int]) -> str:
    """One line for the run summary."""
    words = [f"{k.replace('_', ' ')} {v}" for k, v in counts.items()
             if v or k in ("edges", "reads")]
    return ", ".join(words)
