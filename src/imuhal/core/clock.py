"""Clocks. The pipeline keeps one clock; drivers that must wait use it, never time.sleep.

On hardware the clock is the OS monotonic clock. When emulated, a simulated clock advances
only when the pipeline (or a driver's wait) tells it to, so runs are deterministic and can go
much faster than real time.
"""

from __future__ import annotations

import time
from typing import Protocol, runtime_checkable


@runtime_checkable
class Clock(Protocol):
    def now_ns(self) -> int:
        """Current time in integer nanoseconds."""

    def sleep_until(self, t_ns: int) -> None:
        """Return once the clock reads at least ``t_ns``."""

    def sleep(self, seconds: float) -> None:
        """Wait ``seconds`` (float seconds)."""


class MonotonicClock:
    """The OS monotonic clock, counted from construction."""

    def __init__(self) -> None:
        self._origin = time.monotonic_ns()

    def now_ns(self) -> int:
        return time.monotonic_ns() - self._origin

    def from_monotonic_ns(self, t_ns: int) -> int:
        """A CLOCK_MONOTONIC time (``time.monotonic_ns()``, a kernel edge time stamp) on
        this clock."""
        return t_ns - self._origin

    def sleep_until(self, t_ns: int) -> None:
        delay = t_ns - self.now_ns()
        if delay > 0:
            time.sleep(delay / 1e9)

    def sleep(self, seconds: float) -> None:
        if seconds > 0:
            time.sleep(seconds)


PACE_CATCH_UP_NS = 100_000_000
"""How far a paced simulated clock may fall behind the wall and still catch up (0.1 s)."""


class SimulatedClock:
    """A clock that moves only when told. ``realtime=True`` paces it against the wall clock:
    it never runs ahead of the wall, and when it has fallen more than ``PACE_CATCH_UP_NS``
    behind (the setup before a run's loop, a slow host) it resumes at the wall's pace from
    where it is, instead of racing through the lag: simulated time never runs faster than
    the wall in a paced run, so a run's "ran X s in Y s wall time" has X <= Y."""

    def __init__(self, start_ns: int = 0, *, realtime: bool = False) -> None:
        self._t_ns = start_ns
        self._realtime = realtime
        self._wall_origin = time.monotonic_ns() - start_ns

    def now_ns(self) -> int:
        return self._t_ns

    def sleep_until(self, t_ns: int) -> None:
        if t_ns > self._t_ns:
            self._t_ns = t_ns
        if self._realtime:
            wall_ns = time.monotonic_ns()
            delay = self._t_ns - (wall_ns - self._wall_origin)
            if delay > 0:
                time.sleep(delay / 1e9)
            elif delay < -PACE_CATCH_UP_NS:
                self._wall_origin = wall_ns - self._t_ns

    def sleep(self, seconds: float) -> None:
        self.sleep_until(self._t_ns + round(seconds * 1e9))
