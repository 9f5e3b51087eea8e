"""Driving a driver the way the pipeline does: poll at the times it asks for, on a
simulated clock shared with its emulator."""

from __future__ import annotations

from collections.abc import Callable

from imuhal.core.clock import SimulatedClock
from imuhal.core.samples import Sample
from imuhal.drivers.base import Driver


def poll_until(driver: Driver, clock: SimulatedClock, next_ns: int, end_ns: int,
               before_poll: Callable[[], None] | None = None) -> tuple[list[Sample], int]:
    """Poll from ``next_ns`` until the schedule passes ``end_ns``; returns the samples and
    the next poll time. ``before_poll`` (e.g. a ``Dither``) runs before each poll."""
    out: list[Sample] = []
    while next_ns <= end_ns:
        clock.sleep_until(next_ns)
        if before_poll is not None:
            before_poll()
        result = driver.poll(clock.now_ns())
        out += result.samples
        next_ns = result.next_poll_ns
    return out, next_ns


def poll_count(driver: Driver, clock: SimulatedClock, n_samples: int, *,
               start: int | None = None, max_polls: int | None = None,
               before_poll: Callable[[], None] | None = None) -> list[Sample]:
    """Poll (from ``start``, default the driver's start time) until ``n_samples`` samples
    came out, or ``max_polls`` polls (default 10 per sample + 20) went by. ``before_poll``
    (e.g. a ``Dither``) runs before each poll."""
    t = driver.start(clock.now_ns()) if start is None else start
    out: list[Sample] = []
    for _ in range(max_polls if max_polls is not None else 10 * n_samples + 20):
        clock.sleep_until(t)
        if before_poll is not None:
            before_poll()
        result = driver.poll(clock.now_ns())
        out += result.samples
        t = result.next_poll_ns
        if len(out) >= n_samples:
            break
    return out
