"""Data-ready lines: a chip's interrupt pin on a GPIO line, watched through the kernel.

A :class:`DataReadyLine` requests one line of a GPIO character device (``/dev/gpiochipN``)
for edge detection through libgpiod v2 (the ``gpiod`` package, extra ``gpio``). The kernel
time-stamps each edge when its interrupt runs and numbers the edges of the line; both come
back from :meth:`DataReadyLine.read_edges`:

* ``timestamp_ns``: CLOCK_MONOTONIC, ns (the clock of ``time.monotonic_ns()``), taken by the
  kernel in the interrupt (on gpio-sim: when the simulated interrupt's work runs);
* ``line_seqno``: 1, 2, 3, ... per line since the request. The kernel counts an edge even
  when its event queue is full and the event is dropped, so a gap in the numbers is edges
  lost, counted in :attr:`DataReadyLine.lost_edges` (never silently).

The line is a file descriptor (:meth:`DataReadyLine.fileno`), readable when edges are queued,
so callers wait with ``select``/``selectors``/``asyncio`` or with ``read_edges(timeout_s)``.

    with DataReadyLine("/dev/gpiochip0", "DRDY") as drdy:
        for edge in drdy.read_edges(timeout_s=0.1):
            ...  # one data-ready pulse: read the chip; edge.timestamp_ns is when it fired
"""

from __future__ import annotations

import importlib
from dataclasses import dataclass
from types import ModuleType
from typing import Any, Literal

from imuhal.core.errors import BusError

EdgeKind = Literal["rising", "falling", "both"]


@dataclass(frozen=True)
class Edge:
    """One edge of a line, as the kernel recorded it."""

    timestamp_ns: int
    """CLOCK_MONOTONIC when the kernel saw the edge, ns."""
    line_seqno: int
    """The edge's number on this line since the request (1 for the first)."""
    rising: bool
    """True for a rising (inactive -> active) edge, False for a falling one."""


def _gpiod() -> ModuleType:
    try:
        return importlib.import_module("gpiod")
    except ImportError as exc:
        raise BusError("the gpiod package (libgpiod v2 bindings) is not installed: "
                       "pip install \"imuhal[gpio]\"") from exc


class DataReadyLine:
    """One GPIO line requested for edge events (see the module docstring).

    ``line``: the offset on the chip or the line's name (``gpio-line-names`` / gpio-sim
    ``name``). ``edge``: which edges are events. ``event_buffer_size``: the kernel's queue of
    unread events (the kernel's default is 16 per line); edges beyond it are lost and counted.
    ``gpiod_module``: the libgpiod bindings to use (tests pass a stand-in; default ``gpiod``).
    """

    def __init__(self, chip: str, line: int | str, *, edge: EdgeKind = "rising",
                 consumer: str = "imuhal", event_buffer_size: int | None = None,
                 gpiod_module: ModuleType | None = None) -> None:
        gpiod = gpiod_module if gpiod_module is not None else _gpiod()
        self.name = f"gpio://{chip}/{line}"
        edges = {"rising": gpiod.line.Edge.RISING, "falling": gpiod.line.Edge.FALLING,
                 "both": gpiod.line.Edge.BOTH}
        settings = gpiod.LineSettings(direction=gpiod.line.Direction.INPUT,
                                      edge_detection=edges[edge],
                                      event_clock=gpiod.line.Clock.MONOTONIC)
        self._rising = gpiod.EdgeEvent.Type.RISING_EDGE
        try:
            self._request: Any = gpiod.request_lines(
                chip, consumer=consumer, config={line: settings},
                event_buffer_size=event_buffer_size)
        except (OSError, ValueError) as exc:
            raise BusError(f"cannot request line {line!r} of {chip} for edge events: {exc}. "
                           "Does the line exist, is it free (gpioinfo), and may you open "
                           "the chip (group gpio)?", bus=self.name) from exc
        self._last_seqno = 0
        self.lost_edges = 0
        """Edges the kernel numbered but could not queue (its event queue was full)."""

    def fileno(self) -> int:
        """The request's file descriptor: readable while edge events are queued."""
        return int(self._request.fd)

    def read_edges(self, timeout_s: float | None = 0.0) -> list[Edge]:
        """The queued edges, oldest first; waits up to ``timeout_s`` seconds for the first
        (0: do not wait, None: wait for ever). An empty list when none came."""
        if not self._request.wait_edge_events(timeout_s):
            return []
        edges = []
        for event in self._request.read_edge_events():
            seqno = int(event.line_seqno)
            self.lost_edges += max(0, seqno - self._last_seqno - 1)
            self._last_seqno = seqno
            edges.append(Edge(int(event.timestamp_ns), seqno, event.event_type == self._rising))
        return edges

    def close(self) -> None:
        """Release the line. Idempotent."""
        if self._request is not None:
            self._request.release()
            self._request = None

    def __enter__(self) -> DataReadyLine:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def __repr__(self) -> str:
        return f"<DataReadyLine {self.name}>"
