"""The bus recording file format (version 3), documented in docs/recording.md.

A file is the 8-byte magic, a little-endian u16 format version, then chunks. A chunk is a u32
payload length, the u32 CRC-32 of the payload and the payload. The first chunk holds the
header (UTF-8 JSON: the profile's YAML text and what the run was); every later chunk holds
records, each a varint length followed by that many bytes (a type byte, then its fields).
Chunks are only ever appended, each once the writer flushes (every ``flush_interval_s`` of wall
time or of data time, whichever comes first), so a power cut loses at most the records of the
last interval and a reader stops cleanly
at the first incomplete or damaged chunk.

Times are int nanoseconds on the run's clock, stored as the signed difference from the time of
the previous record (zig-zag varint): a few bytes each.

Version 2 added byte streams (a UART's received bytes and baud-rate changes) and late polls;
version 3 the edges of data-ready lines (kernel time stamp and line sequence number). An
older file has none of the newer records and reads as before.
"""

from __future__ import annotations

import json
import os
import struct
import time
import zlib
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import IO, Any

from imuhal.bus.base import BusKind
from imuhal.bus.spy import OP_BAUD, OP_RECEIVE, OP_TRANSFER
from imuhal.core.errors import ImuhalError

MAGIC = b"\x89IMUREC\n"
"""High bit first (catches 7-bit transfers), a name, a newline (catches newline mangling)."""
FORMAT_VERSION = 3
READABLE_VERSIONS = (1, 2, 3)
"""Version 1 is version 2 without record types 6-9, version 2 is version 3 without type 10:
the same reader reads all three."""
_CHUNK_HEAD = struct.Struct("<II")  # payload length, CRC-32 of the payload
_MAX_CHUNK = 1 << 26  # a length beyond this is damage, not data

REC_BUS = 1
"""A bus of the run: index, profile name, the bus's own name, its kind."""
REC_TRANSFER = 2
"""A completed transaction: dt, bus index, target, bytes written, bytes read."""
REC_FAILED = 3
"""A transaction that raised: dt, bus index, target, written, read length, error type, text."""
REC_CLOCK = 4
"""A reading of the run's clock by a driver or the pipeline: dt."""
REC_END = 5
"""The run closed the recording: how it ended (UTF-8)."""
REC_RECEIVE = 6
"""Bytes a byte-stream bus (a UART) had received: dt, bus index, target, max length, bytes."""
REC_BAUD = 7
"""A byte-stream bus changed its line speed: dt, bus index, baud rate."""
REC_LATE_POLL = 8
"""A poll that happened after it was due (the board was late): dt (the poll's time), device."""
REC_STREAM_FAILED = 9
"""A receive or baud change that raised: dt, bus index, operation (6 receive, 7 baud),
target, max length or baud rate, error type, error text."""

REC_EDGE = 10
"""An edge of a device's data-ready line, as the pipeline took it: dt (the edge's time stamp
on the run's clock), the line's sequence number, device."""

_NEWEST_TYPE = {1: REC_END, 2: REC_STREAM_FAILED}
"""The last record type each older version has (a newer one in its file is damage; an
unknown type in a current file ends it as written by a newer imuhal)."""

_STREAM_OPS = {REC_RECEIVE: OP_RECEIVE, REC_BAUD: OP_BAUD}
_BUS_KINDS = frozenset(kind.value for kind in BusKind)


class RecordingError(ImuhalError):
    """A file is not a recording this imuhal can read; the message names the file."""


class RecordingWriteFailed(Exception):
    """The recording could not be written (disk full, medium gone).

    Not an ImuhalError: it surfaces inside a bus transaction, where the pipeline would take
    an ImuhalError for a device fault and keep retrying; the run has to stop instead.
    """


@dataclass(frozen=True, slots=True)
class BusInfo:
    index: int
    name: str
    """The bus's name in the profile (``buses:`` key)."""
    label: str
    """The name the bus reported at run time (``emul://spi0``, ``i2c:///dev/i2c-1``)."""
    kind: str


@dataclass(frozen=True, slots=True)
class RecordedTransfer:
    """One transaction: a transfer (write, then read ``read_len`` bytes), a receive from a
    byte stream (``read`` is what had arrived, ``read_len`` the most asked for) or a baud-rate
    change (``baudrate``; ``target`` 0, nothing written or read)."""

    index: int
    """Position among the recording's transactions, from 0."""
    t_ns: int
    bus: int
    target: int
    written: bytes
    read: bytes
    read_len: int
    error_type: str = ""
    error: str = ""
    op: str = OP_TRANSFER
    """``transfer``, ``receive`` or ``baud``."""
    baudrate: int = 0


@dataclass(frozen=True, slots=True)
class ClockReading:
    t_ns: int


@dataclass(frozen=True, slots=True)
class EndMark:
    t_ns: int
    how: str
    end_ns: int | None = None
    """When the run ended on its clock (its last poll came before it), when the writer
    knew it; None in a recording made before the end record carried it."""


@dataclass(frozen=True, slots=True)
class LatePoll:
    """The board polled ``device`` late, at ``t_ns`` (an injected late poll or jitter on an
    emulated board): a replay polls it at the same time."""

    t_ns: int
    device: str


@dataclass(frozen=True, slots=True)
class RecordedEdge:
    """An edge of ``device``'s data-ready line the recorded run took: its time stamp and
    the line's sequence number (imuhal.pipeline.triggers)."""

    t_ns: int
    device: str
    seqno: int


Record = BusInfo | RecordedTransfer | ClockReading | EndMark | LatePoll | RecordedEdge


# -- varints -------------------------------------------------------------------------------

def _put_uvarint(out: bytearray, value: int) -> None:
    while value > 0x7F:
        out.append((value & 0x7F) | 0x80)
        value >>= 7
    out.append(value)


def _put_svarint(out: bytearray, value: int) -> None:
    _put_uvarint(out, (value << 1) if value >= 0 else ((-value << 1) - 1))


def _put_bytes(out: bytearray, data: bytes) -> None:
    _put_uvarint(out, len(data))
    out += data


def _put_error(out: bytearray, error_type: str, error: str) -> None:
    _put_bytes(out, error_type.encode("utf-8"))
    _put_bytes(out, error.encode("utf-8"))


def _get_uvarint(buf: bytes, pos: int) -> tuple[int, int]:
    value = buf[pos]
    if value < 0x80:  # most lengths, buses and targets: one byte
        return value, pos + 1
    value = 0
    shift = 0
    while True:
        byte = buf[pos]
        pos += 1
        value |= (byte & 0x7F) << shift
        if byte < 0x80:
            return value, pos
        shift += 7


def _get_svarint(buf: bytes, pos: int) -> tuple[int, int]:
    raw, pos = _get_uvarint(buf, pos)
    return (raw >> 1) if not raw & 1 else -((raw + 1) >> 1), pos


def _get_bytes(buf: bytes, pos: int) -> tuple[bytes, int]:
    n, pos = _get_uvarint(buf, pos)
    return bytes(buf[pos:pos + n]), pos + n


# -- writing -------------------------------------------------------------------------------

class RecordingWriter:
    """Appends records to a new file. ``header`` is any JSON-able mapping.

    The file is created exclusively: a recording is never overwritten. Records are buffered
    and written as one chunk, flushed and fsync'ed, every ``flush_interval_s`` of wall time
    or of the records' own (data) time, whichever comes first (checked at each record), and
    on ``close``.
    """

    def __init__(self, path: str | os.PathLike[str], header: dict[str, Any], *,
                 flush_interval_s: float = 1.0) -> None:
        self.path = Path(path)
        try:
            self._file: IO[bytes] | None = self.path.open("xb")
        except FileExistsError:
            raise RecordingError(f"{self.path}: already exists; a recording is never "
                                 "overwritten - give a new file name or remove the old "
                                 "one") from None
        except OSError as exc:
            raise RecordingError(f"{self.path}: cannot create: {exc.strerror or exc}") from None
        self.flush_interval_s = flush_interval_s
        self._buffer = bytearray()
        self._last_t_ns = 0
        self._last_flush = time.monotonic()
        self._flushed_t_ns = 0
        """Data time of the last record when the last chunk was written."""
        self.transfers = 0
        self._file.write(MAGIC + struct.pack("<H", FORMAT_VERSION))
        self._write_chunk(json.dumps(header, sort_keys=True).encode("utf-8"))

    def _dt(self, t_ns: int) -> int:
        dt = t_ns - self._last_t_ns
        self._last_t_ns = t_ns
        return dt

    def _append(self, body: bytearray) -> None:
        _put_uvarint(self._buffer, len(body))
        self._buffer += body
        # Bounded in both times: wall time for a slow run, data time for a run the CPU
        # races through (an emulated board) or one that a loaded machine starves of wall
        # clock checks, so a kill loses at most one interval of the recorded run either way.
        if (time.monotonic() - self._last_flush >= self.flush_interval_s
                or self._last_t_ns - self._flushed_t_ns >= self.flush_interval_s * 1e9):
            self.flush()

    def bus(self, info: BusInfo) -> None:
        body = bytearray((REC_BUS,))
        _put_uvarint(body, info.index)
        for text in (info.name, info.label, info.kind):
            _put_bytes(body, text.encode("utf-8"))
        self._append(body)

    def _timed(self, kind: int, t_ns: int, *numbers: int) -> bytearray:
        """A record's start: its kind, the time since the previous record, then ``numbers``
        as unsigned varints (bus, target, ...)."""
        body = bytearray((kind,))
        _put_svarint(body, self._dt(t_ns))
        for number in numbers:
            _put_uvarint(body, number)
        return body

    def _append_bus_op(self, body: bytearray) -> None:
        self.transfers += 1
        self._append(body)

    def transfer(self, t_ns: int, bus: int, target: int, written: bytes, read: bytes) -> None:
        body = self._timed(REC_TRANSFER, t_ns, bus, target)
        _put_bytes(body, written)
        _put_bytes(body, read)
        self._append_bus_op(body)

    def failed(self, t_ns: int, bus: int, target: int, written: bytes, read_len: int,
               error_type: str, error: str) -> None:
        body = self._timed(REC_FAILED, t_ns, bus, target)
        _put_bytes(body, written)
        _put_uvarint(body, read_len)
        _put_error(body, error_type, error)
        self._append_bus_op(body)

    def received(self, t_ns: int, bus: int, target: int, max_len: int, data: bytes) -> None:
        body = self._timed(REC_RECEIVE, t_ns, bus, target, max_len)
        _put_bytes(body, data)
        self._append_bus_op(body)

    def baudrate(self, t_ns: int, bus: int, baudrate: int) -> None:
        self._append_bus_op(self._timed(REC_BAUD, t_ns, bus, baudrate))

    def stream_failed(self, t_ns: int, bus: int, op: str, target: int, value: int,
                      error_type: str, error: str) -> None:
        """A failed receive (``value``: the most bytes asked for) or baud change (the rate)."""
        body = self._timed(REC_STREAM_FAILED, t_ns, bus)
        body.append(REC_RECEIVE if op == OP_RECEIVE else REC_BAUD)
        _put_uvarint(body, target)
        _put_uvarint(body, value)
        _put_error(body, error_type, error)
        self._append_bus_op(body)

    def late_poll(self, t_ns: int, device: str) -> None:
        body = self._timed(REC_LATE_POLL, t_ns)
        _put_bytes(body, device.encode("utf-8"))
        self._append(body)

    def clock(self, t_ns: int) -> None:
        self._append(self._timed(REC_CLOCK, t_ns))

    def edge(self, t_ns: int, device: str, seqno: int) -> None:
        body = self._timed(REC_EDGE, t_ns, seqno)
        _put_bytes(body, device.encode("utf-8"))
        self._append(body)

    def end(self, how: str, end_ns: int | None = None) -> None:
        """The end record: how the run ended, then (when known) when, as a dt: a field
        after ``how`` that a reader of before skips with the rest of the record."""
        body = bytearray((REC_END,))
        _put_bytes(body, how.encode("utf-8"))
        if end_ns is not None:
            _put_svarint(body, self._dt(end_ns))
        self._append(body)

    def flush(self) -> None:
        """Write the buffered records as one chunk and make them durable."""
        self._last_flush = time.monotonic()
        self._flushed_t_ns = self._last_t_ns
        if self._buffer and self._file is not None:
            self._write_chunk(bytes(self._buffer))
            self._buffer.clear()

    def _write_chunk(self, payload: bytes) -> None:
        assert self._file is not None
        try:
            self._file.write(_CHUNK_HEAD.pack(len(payload), zlib.crc32(payload)) + payload)
            self._file.flush()
            os.fsync(self._file.fileno())
        except OSError as exc:
            raise RecordingWriteFailed(f"{self.path}: cannot write the recording: "
                                       f"{exc.strerror or exc}") from exc

    @property
    def closed(self) -> bool:
        return self._file is None

    def close(self) -> None:
        if self._file is not None:
            try:
                self.flush()
            finally:
                self._file.close()
                self._file = None


# -- reading -------------------------------------------------------------------------------

@dataclass
class Recording:
    """An open recording: ``header`` now, ``records()`` streamed from the file."""

    path: Path
    version: int
    header: dict[str, Any]
    damage: str = ""
    """Set once ``records()`` stopped early: why (a power cut leaves an incomplete chunk)."""
    buses: dict[int, BusInfo] = field(default_factory=dict)
    end: EndMark | None = None

    def records(self) -> Iterator[Record]:
        """Every record in order; stops at the first incomplete or damaged chunk."""
        index = 0
        t_ns = 0
        with self.path.open("rb") as f:
            f.seek(len(MAGIC) + 2)
            _read_chunk(f, self.path)  # the header, already parsed
            while True:
                offset = f.tell()
                try:
                    payload = _read_chunk(f, self.path)
                except RecordingError as exc:
                    self.damage = f"{exc} (at byte {offset})"
                    return
                if payload is None:
                    return
                try:
                    for record in self._decode(payload, t_ns, index):
                        if isinstance(record, str):  # a record type this reader does not know
                            self.damage = record
                            return
                        if isinstance(record, RecordedTransfer):
                            t_ns, index = record.t_ns, record.index + 1
                        elif isinstance(record, ClockReading | LatePoll | RecordedEdge):
                            t_ns = record.t_ns
                        yield record
                except (IndexError, UnicodeDecodeError, ValueError) as exc:
                    # The chunk passed its CRC, so it is as written, but its records do not
                    # parse: a writer that went wrong or a crafted file. Stop there, as at a
                    # damaged chunk.
                    self.damage = (f"{self.path}: a chunk holds garbled records "
                                   f"({type(exc).__name__}): damaged (at byte {offset})")
                    return

    def _decode(self, payload: bytes, t_ns: int, index: int) -> Iterator[Record | str]:
        """The records of one chunk (times and transaction numbers go on from ``t_ns`` and
        ``index``); a string instead of a record says why decoding stopped."""
        pos = 0
        while pos < len(payload):
            length, p = _get_uvarint(payload, pos)
            pos = p + length
            if pos > len(payload):
                raise IndexError("a record runs past the end of its chunk")
            kind = payload[p]
            p += 1
            if kind > _NEWEST_TYPE.get(self.version, 255):
                yield (f"{self.path}: record type {kind} in a version-{self.version} "
                       "recording: damaged")
                return
            if kind in (REC_TRANSFER, REC_FAILED):
                dt, p = _get_svarint(payload, p)
                t_ns += dt
                bus, p = _get_uvarint(payload, p)
                target, p = _get_uvarint(payload, p)
                written, p = _get_bytes(payload, p)
                if kind == REC_TRANSFER:
                    read, p = _get_bytes(payload, p)
                    yield RecordedTransfer(index, t_ns, bus, target, written, read, len(read))
                else:
                    read_len, p = _get_uvarint(payload, p)
                    etype, p = _get_bytes(payload, p)
                    error, p = _get_bytes(payload, p)
                    yield RecordedTransfer(index, t_ns, bus, target, written, b"", read_len,
                                           etype.decode(), error.decode())
                index += 1
            elif kind == REC_CLOCK:
                dt, _ = _get_svarint(payload, p)
                t_ns += dt
                yield ClockReading(t_ns)
            elif kind == REC_RECEIVE:
                dt, p = _get_svarint(payload, p)
                t_ns += dt
                bus, p = _get_uvarint(payload, p)
                target, p = _get_uvarint(payload, p)
                max_len, p = _get_uvarint(payload, p)
                data, p = _get_bytes(payload, p)
                yield RecordedTransfer(index, t_ns, bus, target, b"", data, max_len,
                                       op=OP_RECEIVE)
                index += 1
            elif kind == REC_BAUD:
                dt, p = _get_svarint(payload, p)
                t_ns += dt
                bus, p = _get_uvarint(payload, p)
                baud, p = _get_uvarint(payload, p)
                yield RecordedTransfer(index, t_ns, bus, 0, b"", b"", 0, op=OP_BAUD,
                                       baudrate=baud)
                index += 1
            elif kind == REC_STREAM_FAILED:
                dt, p = _get_svarint(payload, p)
                t_ns += dt
                bus, p = _get_uvarint(payload, p)
                op = _STREAM_OPS.get(payload[p], "")
                target, p = _get_uvarint(payload, p + 1)
                value, p = _get_uvarint(payload, p)
                etype, p = _get_bytes(payload, p)
                error, p = _get_bytes(payload, p)
                if not op:
                    yield f"{self.path}: a failed stream record names an unknown operation"
                    return
                yield RecordedTransfer(
                    index, t_ns, bus, target, b"", b"", value if op == OP_RECEIVE else 0,
                    etype.decode(), error.decode(), op=op,
                    baudrate=value if op == OP_BAUD else 0)
                index += 1
            elif kind in (REC_LATE_POLL, REC_EDGE):
                timed = _device_record(kind, payload, p, t_ns)
                t_ns = timed.t_ns
                yield timed
            elif kind == REC_BUS:
                bus_index, p = _get_uvarint(payload, p)
                texts = []
                for _ in range(3):
                    raw, p = _get_bytes(payload, p)
                    texts.append(raw.decode("utf-8"))
                if texts[2] not in _BUS_KINDS:
                    raise ValueError(f"bus kind {texts[2]!r}")
                info = BusInfo(bus_index, *texts)
                self.buses[bus_index] = info
                yield info
            elif kind == REC_END:
                how, p = _get_bytes(payload, p)
                end_ns = None
                if p < pos:  # the run's end time, after how (written since poll plan 2)
                    dt, p = _get_svarint(payload, p)
                    end_ns = t_ns + dt
                self.end = EndMark(t_ns, how.decode("utf-8"), end_ns)
                yield self.end
            else:
                yield f"{self.path}: unknown record type {kind} (written by a newer imuhal?)"
                return


def _device_record(kind: int, payload: bytes, p: int, t_ns: int) -> LatePoll | RecordedEdge:
    """A late poll or an edge (both: dt, then their numbers, then the device)."""
    dt, p = _get_svarint(payload, p)
    t_ns += dt
    if kind == REC_EDGE:
        seqno, p = _get_uvarint(payload, p)
        device, p = _get_bytes(payload, p)
        return RecordedEdge(t_ns, device.decode("utf-8"), seqno)
    device, p = _get_bytes(payload, p)
    return LatePoll(t_ns, device.decode("utf-8"))


def _read_chunk(f: IO[bytes], path: Path) -> bytes | None:
    head = f.read(_CHUNK_HEAD.size)
    if not head:
        return None
    if len(head) < _CHUNK_HEAD.size:
        raise RecordingError(f"{path}: the last chunk is cut short")
    length, crc = _CHUNK_HEAD.unpack(head)
    if length > _MAX_CHUNK:
        raise RecordingError(f"{path}: a chunk claims {length} bytes: damaged")
    payload = f.read(length)
    if len(payload) < length:
        raise RecordingError(f"{path}: the last chunk is cut short")
    if zlib.crc32(payload) != crc:
        raise RecordingError(f"{path}: a chunk fails its CRC check: damaged")
    return payload


def open_recording(path: str | os.PathLike[str]) -> Recording:
    """Check the magic, version and header of the recording at ``path``."""
    p = Path(path)
    try:
        f = p.open("rb")
    except OSError as exc:
        raise RecordingError(f"{p}: cannot read: {exc.strerror or exc}") from None
    with f:
        start = f.read(len(MAGIC) + 2)
        if start[:len(MAGIC)] != MAGIC:
            raise RecordingError(f"{p}: not an imuhal bus recording (make one with "
                                 "`imuhal run --record FILE`)")
        (version,) = struct.unpack("<H", start[len(MAGIC):])
        if version not in READABLE_VERSIONS:
            raise RecordingError(
                f"{p}: recording format version {version}; this imuhal reads versions "
                f"{READABLE_VERSIONS[0]}-{READABLE_VERSIONS[-1]}"
                + (" (upgrade imuhal to replay it)" if version > FORMAT_VERSION else ""))
        try:
            payload = _read_chunk(f, p)
            if payload is None:
                raise RecordingError(f"{p}: the header is missing")
            header = json.loads(payload.decode("utf-8"))
        except (ValueError, RecordingError) as exc:
            raise RecordingError(f"{p}: unreadable header ({exc})") from None
        except RecursionError:
            raise RecordingError(f"{p}: unreadable header (nested too deep)") from None
    if not isinstance(header, dict):
        raise RecordingError(f"{p}: unreadable header (a JSON {type(header).__name__}, not "
                             "an object)")
    return Recording(p, version, header)
