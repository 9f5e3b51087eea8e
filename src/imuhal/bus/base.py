"""The bus primitive every driver talks through, on hardware and in emulation alike.

A bus carries transactions to targets: an I2C 7-bit address or an SPI chip select. One
transaction writes ``write`` and then reads ``read_len`` bytes (I2C: a write then a read with
repeated start; SPI: one chip-select assertion clocking ``write`` out and ``read_len`` bytes
in). Each transaction holds the bus lock, so drivers on different threads never interleave.
"""

from __future__ import annotations

import threading
from abc import ABC, abstractmethod
from dataclasses import dataclass
from enum import Enum


class BusKind(str, Enum):
    I2C = "i2c"
    SPI = "spi"
    SERIAL = "serial"
    IIO = "iio"
    """Linux Industrial I/O: chips bound to kernel drivers, read through sysfs and
    /dev/iio:deviceN (imuhal.bus.linux_iio)."""


class Bus(ABC):
    """A bus shared by the devices on it. Subclasses implement ``_transfer``."""

    kind: BusKind

    def __init__(self, name: str) -> None:
        self.name = name
        self.lock = threading.RLock()
        self.transfers = 0

    def transfer(self, target: int, write: bytes = b"", read_len: int = 0) -> bytes:
        """One transaction with ``target``; returns exactly ``read_len`` bytes."""
        if type(write) is not bytes:  # a bytearray or memoryview: the callee gets a copy
            write = bytes(write)
        with self.lock:
            self.transfers += 1
            data = self._transfer(target, write, read_len)
        if len(data) != read_len:
            from imuhal.core.errors import BusError

            raise BusError(f"short read: {len(data)} of {read_len} bytes", bus=self.name,
                           target=target)
        return data

    @abstractmethod
    def _transfer(self, target: int, write: bytes, read_len: int) -> bytes: ...

    def receive(self, target: int, max_len: int) -> bytes:
        """Byte streams (a UART): up to ``max_len`` bytes that have already arrived from
        ``target``, without waiting (b"" when none). A device that talks unprompted (a GNSS
        receiver) is read this way; register-mapped chips use :meth:`transfer`."""
        with self.lock:
            return self._receive(target, max_len)

    def _receive(self, target: int, max_len: int) -> bytes:
        from imuhal.core.errors import BusError

        raise BusError(f"a {self.kind.value} bus carries transactions, not a byte stream",
                       bus=self.name, target=target)

    def link(self, target: int) -> Link:
        """A handle bound to one target, which is what a driver keeps."""
        return Link(self, target)

    def describe(self) -> str:
        """The bus as a summary names it: its name, plus how it reaches its devices where
        that was chosen at run time (e.g. an I2C adapter's transfer mode)."""
        return self.name

    def close(self) -> None:  # noqa: B027 - optional for backends without resources
        """Release OS resources. Idempotent."""

    def __enter__(self) -> Bus:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def __repr__(self) -> str:
        return f"<{type(self).__name__} {self.name}>"


@dataclass(frozen=True)
class Link:
    """A bus plus one target: the address or chip select of one device."""

    bus: Bus
    target: int

    @property
    def kind(self) -> BusKind:
        return self.bus.kind

    def transfer(self, write: bytes = b"", read_len: int = 0) -> bytes:
        return self.bus.transfer(self.target, write, read_len)

    def receive(self, max_len: int) -> bytes:
        """Up to ``max_len`` bytes already received (byte-stream buses only)."""
        return self.bus.receive(self.target, max_len)

    def describe(self) -> str:
        return f"{self.bus.name} target 0x{self.target:02X}"
