"""A bus wrapper that records every transaction: the first thing to attach to a bug report.

``SpyBus(inner, record)`` forwards each transaction to ``inner`` unchanged and hands a
``Transfer`` (bus, target, bytes written, bytes read or the error) to ``record``.
``format_transfer`` renders one as a line: ``spi0 @01 W:a0 R:9c 4f`` or ``... ERR:...``.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

from imuhal.bus.base import Bus, Link
from imuhal.core.clock import Clock


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
    """Bytes asked for (-1: not noted); a failed transaction read none of them."""


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
                                 f"{type(exc).__name__}: {exc}", read_len))
            raise
        self.record(Transfer(self.clock.now_ns(), self.name, target, write, data,
                             read_len=read_len))
        return data

    def _receive(self, target: int, max_len: int) -> bytes:
        # A UART's unprompted bytes pass through unlogged: --trace shows transactions.
        return self.inner.receive(target, max_len)

    def __getattr__(self, name: str) -> object:
        # Optional capabilities of the spied bus (a UART's set_baudrate) stay reachable.
        return getattr(self.inner, name)

    def link(self, target: int) -> Link:
        return Link(self, target)

    def close(self) -> None:
        self.inner.close()


def format_transfer(t: Transfer) -> str:
    head = f"{t.t_ns / 1e9:12.6f} {t.bus} @{t.target:02X} W:{t.written.hex(' ') or '-'}"
    if t.error:
        return f"{head} ERR:{t.error}"
    return f"{head} R:{t.read.hex(' ') or '-'}"
