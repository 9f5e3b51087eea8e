"""The recording side: the spy bus's transactions and every clock reading, into a file.

Replaying a hardware run exactly needs more than the bytes: drivers read the clock (data-ready
deadlines, sample times), so every ``now_ns()`` the drivers and the pipeline make is recorded
too, in order with the transactions, and so is every poll the board made late and every
edge of a data-ready line the pipeline took. A byte-stream
bus (a UART) is recorded as what the driver saw of it: each receive's bytes and each
baud-rate change.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Mapping
from datetime import datetime, timezone
from typing import Any

from imuhal import __version__
from imuhal.bus.base import Bus
from imuhal.bus.recording.format import (
    BusInfo,
    RecordingError,
    RecordingWriteFailed,
    RecordingWriter,
)
from imuhal.bus.spy import OP_BAUD, OP_RECEIVE, Transfer
from imuhal.core.clock import Clock
from imuhal.core.poll_plan import POLL_PLAN


class RecordingClock:
    """Forwards to ``inner`` and records each reading of it."""

    def __init__(self, inner: Clock, writer: RecordingWriter) -> None:
        self.inner = inner
        self._writer = writer

    def now_ns(self) -> int:
        t = self.inner.now_ns()
        self._writer.clock(t)
        return t

    def sleep_until(self, t_ns: int) -> None:
        self.inner.sleep_until(t_ns)

    def sleep(self, seconds: float) -> None:
        self.inner.sleep(seconds)


class BusRecorder:
    """Receives a pipeline's buses, transactions (from the spy bus) and clock readings.

    ``header`` describes the run; :func:`run_header` builds the usual one, which carries the
    profile text so a replay needs nothing but the file.
    """

    def __init__(self, path: str | os.PathLike[str], header: dict[str, Any], *,
                 flush_interval_s: float = 1.0) -> None:
        self.writer = RecordingWriter(path, header, flush_interval_s=flush_interval_s)
        self._bus_index: dict[str, int] = {}
        self._clock: Clock | None = None

    @property
    def transfers(self) -> int:
        return self.writer.transfers

    def attach(self, buses: Mapping[str, Bus]) -> None:
        """Note the run's buses (profile name, run-time name, kind) before any transfer."""
        for name, bus in buses.items():
            index = len(self._bus_index)
            self._bus_index[bus.name] = index
            self.writer.bus(BusInfo(index, name, bus.name, bus.kind.value))

    def wrap_clock(self, clock: Clock) -> RecordingClock:
        self._clock = clock  # read unrecorded at the end: when the run ended (close)
        return RecordingClock(clock, self.writer)

    def wrap_before_poll(self, before_poll: Callable[[int, str], int]
                         ) -> Callable[[int, str], int]:
        """The board's ``before_poll``, recording each poll it makes late (an emulated
        board's injected late polls and jitter): a replay polls at the recorded time."""
        def recorded(t_ns: int, device: str) -> int:
            at_ns = before_poll(t_ns, device)
            if at_ns != t_ns:
                self.writer.late_poll(at_ns, device)
            return at_ns
        return recorded

    def on_edge(self, device: str, t_ns: int, seqno: int) -> None:
        """An edge of ``device``'s data-ready line that the pipeline took (time stamp on the
        run's clock, the line's sequence number): a replay hands it over at this point."""
        self.writer.edge(t_ns, device, seqno)

    def on_transfer(self, t: Transfer) -> None:
        bus = self._bus_index[t.bus]
        error_type, _, message = t.error.partition(": ")
        if t.op == OP_RECEIVE:
            if t.error:
                self.writer.stream_failed(t.t_ns, bus, t.op, t.target, t.read_len, error_type,
                                          message)
            else:
                self.writer.received(t.t_ns, bus, t.target, t.read_len, t.read)
        elif t.op == OP_BAUD:
            if t.error:
                self.writer.stream_failed(t.t_ns, bus, t.op, 0, t.baudrate, error_type,
                                          message)
            else:
                self.writer.baudrate(t.t_ns, bus, t.baudrate)
        elif t.error:
            self.writer.failed(t.t_ns, bus, t.target, t.written, t.read_len, error_type,
                               message)
        else:
            self.writer.transfer(t.t_ns, bus, t.target, t.written, t.read)

    def close(self, how: str = "complete") -> None:
        """Mark how the run ended and make everything durable."""
        if self.writer.closed:
            return
        try:
            # when the run ended: a replay polls nothing from then on, not even a device
            # whose polls make no transaction (a slave its master auto-reads)
            self.writer.end(how, None if self._clock is None else self._clock.now_ns())
        finally:
            try:
                self.writer.close()
            except RecordingWriteFailed as exc:
                # Outside the pipeline now: an ordinary error the CLI reports in one line.
                raise RecordingError(str(exc)) from None


def run_header(profile_text: str, profile_source: str, *, emulate: str | None,
               seed: int | None) -> dict[str, Any]:
    """What a recording says about its run (docs/recording.md, "Header")."""
    return {
        "imuhal_version": __version__,
        "poll_plan": POLL_PLAN,
        "created_utc": datetime.now(timezone.utc).isoformat(timespec="seconds"),
        "profile_source": profile_source,
        "profile_yaml": profile_text,
        "emulate": emulate,
        "seed": seed,
    }
