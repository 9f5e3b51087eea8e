"""The replay side: a Bus and a Clock that answer from a recording, checking every question.

Each transaction a driver asks for must be the next one recorded (same bus, target, bytes
written and read length; for a UART the same receive or baud-rate change), and each clock
reading must come where one was recorded; the first difference stops the replay with
:class:`ReplayDivergence`, one line naming the transaction. A poll the recorded run made late
is made at the recorded time.
Recorded failures are raised again as the same error types, so the pipeline's recovery runs
exactly as it did live.
"""

from __future__ import annotations

import os
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

from imuhal.bus.base import Bus, BusKind
from imuhal.bus.recording.format import (
    BusInfo,
    ClockReading,
    EndMark,
    LatePoll,
    Record,
    RecordedEdge,
    RecordedTransfer,
    Recording,
    RecordingError,
    open_recording,
)
from imuhal.bus.spy import OP_BAUD, OP_RECEIVE, OP_TRANSFER
from imuhal.core import errors as error_types
from imuhal.core.errors import BusError, ImuhalError, RunEnded
from imuhal.core.poll_plan import FIRST_POLL_PLAN, POLL_PLAN
from imuhal.pipeline.pipeline import Pipeline
from imuhal.pipeline.triggers import TriggerEdge
from imuhal.plugins.manager import Registry
from imuhal.profile.loader import parse_profile
from imuhal.profile.model import BoardProfile

if TYPE_CHECKING:
    from imuhal.sinks.base import Event, Sink


class ReplayDivergence(RunEnded):
    """The drivers asked for something other than what was recorded.

    Deliberately not an ImuhalError: the pipeline treats those as device faults and recovers,
    which here would only diverge further.
    """


class EndOfRecording(RunEnded):
    """The recording has no more records: the replayed run is over."""


def _describe(bus: str, target: int, written: bytes, read_len: int, op: str = OP_TRANSFER,
              baudrate: int = 0) -> str:
    if op == OP_RECEIVE:
        return f"{bus} @{target:02X} RX({read_len})"
    if op == OP_BAUD:
        return f"{bus} BAUD {baudrate}"
    return f"{bus} @{target:02X} W:{written.hex(' ') or '-'} R({read_len})"


class ReplaySource:
    """The shared cursor over a recording's records."""

    def __init__(self, recording: Recording) -> None:
        self.recording = recording
        self._records = recording.records()
        self._pending: Record | None = None
        self.buses: dict[int, BusInfo] = {}
        self.transfers = 0
        """Transactions replayed so far."""
        self.t_ns = 0
        """Time of the last record replayed."""
        while isinstance(self._peek(), BusInfo):
            info = self._take()
            assert isinstance(info, BusInfo)
            self.buses[info.index] = info

    def _peek(self) -> Record | None:
        if self._pending is None:
            self._pending = next(self._records, None)
        return self._pending

    def _take(self) -> Record | None:
        rec = self._peek()
        self._pending = None
        return rec

    def _next(self, asked: Callable[[], str]) -> ClockReading | RecordedTransfer:
        """The next clock reading or transaction; ``asked()`` (what the run asks for, in
        words) names the divergence when the recording has a late poll here instead."""
        rec = self._take()
        while isinstance(rec, BusInfo):
            rec = self._take()
        if rec is None or isinstance(rec, EndMark):
            raise EndOfRecording()
        if isinstance(rec, LatePoll | RecordedEdge):
            what = f"polls {rec.device} late" if isinstance(rec, LatePoll) else \
                f"has an edge of {rec.device}'s data-ready line"
            raise ReplayDivergence(
                f"replay diverged after transaction {self.transfers - 1} (t="
                f"{rec.t_ns / 1e9:.6f} s): the recording {what} here, {asked()}")
        return rec

    def edges(self, device: str | None = None) -> list[RecordedEdge]:
        """The data-ready edges recorded next (of ``device`` only, when given): what the
        recorded run took from its lines at this point."""
        taken = []
        while isinstance(rec := self._peek(), RecordedEdge) and \
                (device is None or rec.device == device):
            self._take()
            taken.append(rec)
        return taken

    def clock(self) -> int:
        rec = self._next(lambda: "the run read the clock")
        if isinstance(rec, RecordedTransfer):
            raise self._divergence(rec, "the run read the clock here")
        self.t_ns = rec.t_ns
        return rec.t_ns

    def poll_time(self, t_ns: int, device: str) -> int:
        """When the recorded run polled ``device``, due at ``t_ns``: later when it was late."""
        rec = self._peek()
        if type(rec) is EndMark and rec.end_ns is not None and t_ns >= rec.end_ns:
            # the recorded run ended before this poll (one that makes no transaction, such
            # as a slave's its master auto-read, would otherwise hand out one more reading)
            raise EndOfRecording()
        if not isinstance(rec, LatePoll) or rec.device != device:
            # Another device's late poll comes next: this poll was on time and leaves no
            # record of its own before it (a driver that reads what another's burst
            # delivered makes no transaction); had it made one, the recording would have it
            # first, and asking for it now meets the late poll, a divergence (_next).
            return t_ns
        self._take()
        self.t_ns = rec.t_ns
        return rec.t_ns

    def transfer(self, bus: int, target: int, written: bytes, read_len: int) -> bytes:
        return self._transaction(OP_TRANSFER, bus, target, written, read_len)

    def receive(self, bus: int, target: int, max_len: int) -> bytes:
        """The bytes the byte-stream bus had received at this point of the recorded run."""
        return self._transaction(OP_RECEIVE, bus, target, b"", max_len)

    def set_baudrate(self, bus: int, baudrate: int) -> None:
        self._transaction(OP_BAUD, bus, 0, b"", 0, baudrate)

    def _transaction(self, op: str, bus: int, target: int, written: bytes, read_len: int,
                     baudrate: int = 0) -> bytes:
        def asked() -> str:  # only needed when the replay diverges
            return "the driver asked " + _describe(self.buses[bus].label, target, written,
                                                   read_len, op, baudrate)

        rec = self._next(asked)
        if isinstance(rec, ClockReading):
            # A recording cut off (or ended) after a poll's clock readings but before its
            # transfers: when only readings are left, the run is over, not diverged.
            while isinstance(self._peek(), ClockReading):
                self._take()
            if self._peek() is None or isinstance(self._peek(), EndMark):
                raise EndOfRecording()
            raise ReplayDivergence(
                f"replay diverged after transaction {self.transfers - 1} (t="
                f"{rec.t_ns / 1e9:.6f} s): the recording reads the clock here, {asked()}")
        if (rec.op, rec.bus, rec.target, rec.written, rec.read_len, rec.baudrate) != (
                op, bus, target, written, read_len, baudrate):
            raise self._divergence(rec, asked())
        self.transfers += 1
        self.t_ns = rec.t_ns
        if rec.error_type:
            raise _recorded_error(rec.error_type, rec.error, self.buses[bus].label, target)
        return rec.read

    def _divergence(self, rec: RecordedTransfer, asked: str) -> ReplayDivergence:
        label = self.buses[rec.bus].label if rec.bus in self.buses else f"bus#{rec.bus}"
        recorded = _describe(label, rec.target, rec.written, rec.read_len, rec.op,
                             rec.baudrate)
        return ReplayDivergence(f"replay diverged at transaction {rec.index} (t="
                                f"{rec.t_ns / 1e9:.6f} s): the recording has {recorded}, "
                                f"{asked}")


def _recorded_error(error_type: str, message: str, bus: str, target: int) -> Exception:
    """The recorded failure as the same exception type with the same text."""
    cls = getattr(error_types, error_type, None)
    if not (isinstance(cls, type) and issubclass(cls, ImuhalError)):
        cls = BusError  # a bus backend's own error type: the pipeline sees a bus error
    exc = cls.__new__(cls)
    Exception.__init__(exc, message)
    if isinstance(exc, BusError):
        exc.bus, exc.target = bus, target
    return exc


class ReplayBus(Bus):
    """One recorded bus; its name is the one the bus had live, so messages read the same."""

    def __init__(self, info: BusInfo, source: ReplaySource) -> None:
        super().__init__(info.label)
        self.kind = BusKind(info.kind)
        self.index = info.index
        self.source = source

    def _transfer(self, target: int, write: bytes, read_len: int) -> bytes:
        return self.source.transfer(self.index, target, write, read_len)

    def _receive(self, target: int, max_len: int) -> bytes:
        if self.kind is not BusKind.SERIAL:
            return super()._receive(target, max_len)
        return self.source.receive(self.index, target, max_len)


class ReplaySerialBus(ReplayBus):
    """A recorded UART: its line-speed changes are transactions too."""

    def set_baudrate(self, baudrate: int) -> None:
        self.source.set_baudrate(self.index, baudrate)


def replay_bus(info: BusInfo, source: ReplaySource) -> ReplayBus:
    """The replay bus of a recorded bus: a UART's can change its line speed, like the live
    one (a driver looks for ``set_baudrate``)."""
    cls = ReplaySerialBus if info.kind == BusKind.SERIAL.value else ReplayBus
    return cls(info, source)


class ReplayClock:
    """Reads are the recorded readings, in order; waits take no time."""

    def __init__(self, source: ReplaySource) -> None:
        self.source = source

    def now_ns(self) -> int:
        return self.source.clock()

    def sleep_until(self, t_ns: int) -> None:
        return None

    def sleep(self, seconds: float) -> None:
        return None


@dataclass
class Replay:
    """What :func:`open_replay` sets up: the profile, the buses and clock, the source."""

    recording: Recording
    profile: BoardProfile
    source: ReplaySource
    buses: dict[str, Bus]
    clock: ReplayClock


def open_replay(path: str | os.PathLike[str], registry: Registry,
                profile: BoardProfile | None = None) -> Replay:
    """Open a recording for replay with its own profile, or ``profile`` (same bus names)."""
    recording = open_recording(path)
    if profile is None:
        text = recording.header.get("profile_yaml")
        if not isinstance(text, str):
            raise RecordingError(f"{path}: the header has no profile; give one with --profile")
        origin = recording.header.get("profile_source", "?")
        profile = parse_profile(text, f"{path} (profile recorded from {origin})", registry)
    source = ReplaySource(recording)
    buses: dict[str, Bus] = {info.name: replay_bus(info, source)
                             for info in source.buses.values()}
    missing = sorted(set(profile.buses) - set(buses))
    if not buses:
        why = f" ({recording.damage})" if recording.damage else ""
        raise RecordingError(f"{path}: the recording holds no bus records{why}: it was cut "
                             "before its first chunk of records was written (a run stopped "
                             "within its first flush interval); nothing to replay")
    if missing:
        raise RecordingError(f"{path}: the profile names bus(es) {', '.join(missing)} but the "
                             f"recording has {', '.join(sorted(buses)) or 'none'}; use a "
                             "profile with the recorded buses")
    return Replay(recording, profile, source, buses, ReplayClock(source))


class ReplayLine:
    """A recorded data-ready line: its edges come from the recording (:class:`ReplayWaiter`)."""

    def __init__(self, device: str) -> None:
        self.name = f"replay://{device}/INT"

    def take_edges(self) -> list[TriggerEdge]:
        return []

    def close(self) -> None:
        return None


class ReplayWaiter:
    """Hands the pipeline the edges the recorded run took, where it took them; no edge
    recorded next: the recorded run's deadline came first."""

    def __init__(self, source: ReplaySource) -> None:
        self.source = source

    def wait(self, deadline_ns: int) -> dict[str, list[TriggerEdge]]:
        woke: dict[str, list[TriggerEdge]] = {}
        for rec in self.source.edges():
            woke.setdefault(rec.device, []).append(TriggerEdge(rec.t_ns, rec.seqno))
        return woke

    def take(self, device: str) -> list[TriggerEdge]:
        return [TriggerEdge(rec.t_ns, rec.seqno) for rec in self.source.edges(device)]


@dataclass
class ReplayBoard:
    """The recorded board as the pipeline sees it (imuhal.pipeline.board.Board)."""

    buses: dict[str, Bus]
    clock: ReplayClock
    lines: dict[str, ReplayLine] = field(default_factory=dict)
    """The data-ready lines of the profile's devices (``interrupt:``), replayed."""
    poll_plan: int = POLL_PLAN
    """The drivers' poll plan the recording was made with (imuhal.core.poll_plan)."""

    def waiter(self) -> ReplayWaiter:
        return ReplayWaiter(self.clock.source)

    def before_poll(self, t_ns: int, device: str) -> int:
        """The chips' answers are in the recording; the poll is at ``t_ns``, or at the
        recorded time when the recorded run polled ``device`` late."""
        return self.clock.source.poll_time(t_ns, device)


def recorded_poll_plan(recording: Recording) -> int:
    """The poll plan ``recording`` was made with: its header's, else the first (a recording
    from before plans had versions)."""
    plan = recording.header.get("poll_plan", FIRST_POLL_PLAN)
    return plan if isinstance(plan, int) else FIRST_POLL_PLAN


def replay_pipeline(replay: Replay, registry: Registry) -> Pipeline:
    """The pipeline of the recorded run, opened (probe, configure) from the recording."""
    lines = {name: ReplayLine(name) for name, dev in replay.profile.devices.items()
             if dev.enabled and dev.interrupt is not None}
    board = ReplayBoard(replay.buses, replay.clock, lines, recorded_poll_plan(replay.recording))
    try:
        return Pipeline(replay.profile, registry, board)
    except EndOfRecording:
        raise RecordingError(f"{replay.recording.path}: the recording ends before the board "
                             "was opened (probe and configuration are incomplete)") from None


def replay_run(pipeline: Pipeline, sinks: Sequence[Sink]) -> None:
    """Run the replayed pipeline into ``sinks`` until the recording ends.

    The sinks are not closed: the caller commits them after a complete replay, or drops them
    when :class:`ReplayDivergence` is raised.
    """
    try:
        pipeline.run(None, [_Unclosed(sinks)])
    except EndOfRecording:
        return


class _Unclosed:
    def __init__(self, sinks: Sequence[Sink]) -> None:
        self.sinks = sinks

    def handle(self, event: Event) -> None:
        for sink in self.sinks:
            sink.handle(event)

    def close(self) -> None:
        return None


class WallClockPace:
    """A sink that holds each event back until as much wall time has passed since the first
    event as recorded time did (``t_ns``): the sinks after it see the recorded run's pace, as
    a broker or a ground station saw the live board, not a burst. It never speeds up: an
    event decoded late is handed on at once."""

    name = "pace"

    def __init__(self, monotonic_s: Callable[[], float] = time.monotonic,
                 sleep_s: Callable[[float], None] = time.sleep) -> None:
        self._monotonic_s = monotonic_s
        self._sleep_s = sleep_s
        self._origin: tuple[int, float] | None = None
        """The first event's recorded time (ns) and the wall clock then (s)."""

    def handle(self, event: Event) -> None:
        if self._origin is None:
            self._origin = (event.t_ns, self._monotonic_s())
            return
        t0_ns, wall0_s = self._origin
        wait_s = wall0_s + (event.t_ns - t0_ns) / 1e9 - self._monotonic_s()
        if wait_s > 0:
            self._sleep_s(wait_s)

    def close(self) -> None:
        return None
