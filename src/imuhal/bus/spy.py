"""A bus wrapper that records every transaction: the first thing to attach to a bug report.

``SpyBus(inner, record)`` forwards each transaction to ``inner`` unchanged and hands a
``Transfer`` (bus, target, bytes written, bytes read or the error) to ``record``. Byte-stream
buses (a UART) are spied on too: each ``receive`` (the bytes that had arrived) and each
``set_baudrate`` is a ``Transfer`` of its own ``op``.
``format_transfer`` renders one as a line: ``spi0 @01 W:a0 R:9c 4f``, ``uart @00 RX(64) R:24
47``, ``uart BAUD 9600`` or ``... ERR:...``.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

from imuhal.bus.base import Bus, Link
from imuhal.core.clock import Clock

OP_TRANSFER = "transfer"
OP_RECEIVE = "receive"
OP_BAUD = "baud"


@dataclass(frozen=True, slots=True)
class Transfer:
    t_ns: int
    bus: str
    target: int
    written: bytes
    read: bytes
    error: str = ""
    """``Type: message`` of the exception the transaction raised; empty when it completed."""
    read_len: int = -1
    """Bytes asked for (-1: not noted); a failed transaction read none of them. For a
    receive: the most bytes asked for (``read`` is what had arrived, often fewer)."""
    op: str = OP_TRANSFER
    """``transfer``, ``receive`` (a byte stream's arrived bytes) or ``baud`` (a line-speed
    change to ``baudrate``)."""
    baudrate: int = 0


class SpyBus(Bus):
    def __init__(self, inner: Bus, record: Callable[[Transfer], None], clock: Clock) -> None:
        super().__init__(inner.name)
        self.kind = inner.kind
        self.inner = inner
        self.record = record
        self.clock = clock
        self.lock = inner.lock  # one lock: the spy must not let transactions interleave

    def _transfer(self, target: int, write: bytes, read_len: int) -> bytes:
        try:
            data = self.inner.transfer(target, write, read_len)
        except Exception as exc:
            self.record(Transfer(self.clock.now_ns(), self.name, target, write, b"",
                                 _error(exc), read_len))
            raise
        self.record(Transfer(self.clock.now_ns(), self.name, target, write, data,
                             read_len=read_len))
        return data

    def _receive(self, target: int, max_len: int) -> bytes:
        try:
            data = self.inner.receive(target, max_len)
        except Exception as exc:
            self.record(Transfer(self.clock.now_ns(), self.name, target, b"", b"",
                                 _error(exc), max_len, OP_RECEIVE))
            raise
        self.record(Transfer(self.clock.now_ns(), self.name, target, b"", data,
                             read_len=max_len, op=OP_RECEIVE))
        return data

    def _set_baudrate(self, baudrate: int) -> None:
        with self.lock:
            try:
                self.inner.set_baudrate(baudrate)  # type: ignore[attr-defined]  # only serial buses have set_baudrate, and only they call this
            except Exception as exc:
                self.record(Transfer(self.clock.now_ns(), self.name, 0, b"", b"", _error(exc),
                                     0, OP_BAUD, baudrate))
                raise
            self.record(Transfer(self.clock.now_ns(), self.name, 0, b"", b"", read_len=0,
                                 op=OP_BAUD, baudrate=baudrate))

    def __getattr__(self, name: str) -> object:
        # Optional capabilities of the spied bus stay reachable, and only where the spied
        # bus has them (a driver probes for set_baudrate); a line-speed change is spied on.
        found = getattr(self.inner, name)
        return self._set_baudrate if name == "set_baudrate" else found

    def link(self, target: int) -> Link:
        return Link(self, target)

    def close(self) -> None:
        self.inner.close()


def _error(exc: Exception) -> str:
    return f"{type(exc).__name__}: {exc}"


def format_transfer(t: Transfer) -> str:
    if t.op == OP_BAUD:
        head = f"{t.t_ns / 1e9:12.6f} {t.bus} BAUD {t.baudrate}"
    elif t.op == OP_RECEIVE:
        head = f"{t.t_ns / 1e9:12.6f} {t.bus} @{t.target:02X} RX({t.read_len})"
    else:
        head = f"{t.t_ns / 1e9:12.6f} {t.bus} @{t.target:02X} W:{t.written.hex(' ') or '-'}"
    if t.error:
        return f"{head} ERR:{t.error}"
    return head if t.op == OP_BAUD else f"{head} R:{t.read.hex(' ') or '-'}"
