"""The recording side: the spy bus's transactions and every clock reading, into a file.

Replaying a hardware run exactly needs more than the bytes: drivers read the clock (data-ready
deadlines, sample times), so every ``now_ns()`` the drivers and the pipeline make is recorded
too, in order with the transactions.
"""

from __future__ import annotations

import os
from collections.abc import Mapping
from datetime import datetime, timezone
from typing import Any

from imuhal import __version__
from imuhal.bus.base import Bus, BusKind
from imuhal.bus.recording.format import (
    BusInfo,
    RecordingError,
    RecordingWriteFailed,
    RecordingWriter,
)
from imuhal.bus.spy import Transfer
from imuhal.core.clock import Clock
from imuhal.core.errors import ImuhalError


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

    @property
    def transfers(self) -> int:
        return self.writer.transfers

    def attach(self, buses: Mapping[str, Bus]) -> None:
        """Note the run's buses (profile name, run-time name, kind) before any transfer.

        Byte-stream buses (a UART with a GNSS receiver) are refused: their unprompted bytes
        are not recorded yet, so a replay could not reproduce the run."""
        streams = [name for name, bus in buses.items() if bus.kind is BusKind.SERIAL]
        if streams:
            raise ImuhalError(f"--record: the serial bus(es) {', '.join(streams)} carry byte "
                              "streams, which recordings do not hold yet; record a profile "
                              "without them, or use --trace for a readable log")
        for name, bus in buses.items():
            index = len(self._bus_index)
            self._bus_index[bus.name] = index
            self.writer.bus(BusInfo(index, name, bus.name, bus.kind.value))

    def wrap_clock(self, clock: Clock) -> RecordingClock:
        return RecordingClock(clock, self.writer)

    def on_transfer(self, t: Transfer) -> None:
        bus = self._bus_index[t.bus]
        if t.error:
            error_type, _, message = t.error.partition(": ")
            self.writer.failed(t.t_ns, bus, t.target, t.written, t.read_len, error_type,
                               message)
        else:
            self.writer.transfer(t.t_ns, bus, t.target, t.written, t.read)

    def close(self, how: str = "complete") -> None:
        """Mark how the run ended and make everything durable."""
        if self.writer.closed:
            return
        try:
            self.writer.end(how)
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
        "created_utc": datetime.now(timezone.utc).isoformat(timespec="seconds"),
        "profile_source": profile_source,
        "profile_yaml": profile_text,
        "emulate": emulate,
        "seed": seed,
    }
