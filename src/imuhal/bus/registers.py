"""Register access on top of a link: address byte conventions per bus kind and chip.

Chips disagree on how a register address byte is built: SPI parts set bit 7 to read (most)
and some clear it to write (BMP280); ST parts set bit 6 to auto-increment while the MAX2110x
set bit 6 to *stop* auto-incrementing. A driver states its chip's convention once, declaratively,
and the view applies it to every access.
"""

from __future__ import annotations

from dataclasses import dataclass

from imuhal.bus.base import BusKind, Link


@dataclass(frozen=True)
class RegisterConvention:
    """How a register address byte is formed for reads and writes."""

    read_set: int = 0x00
    """Bits OR-ed into the address byte of a read (SPI: usually 0x80)."""
    write_clear: int = 0x00
    """Bits cleared from the address byte of a write (BMP280 SPI: 0x80)."""
    burst_set: int = 0x00
    """Bits OR-ed in for a multi-byte read (ST parts: 0x40)."""
    single_set: int = 0x00
    """Bits OR-ed in for a single-register access that must not increment (MAX2110x: 0x40)."""
    pairwise_burst_write: bool = False
    """Multi-byte writes are (address, data) pairs rather than an auto-incremented run."""

    @classmethod
    def i2c(cls) -> RegisterConvention:
        return cls()

    @classmethod
    def spi_read_bit7(cls) -> RegisterConvention:
        return cls(read_set=0x80)


class RegisterView:
    """Read and write 8-bit-addressed registers of one device."""

    def __init__(self, link: Link, convention: RegisterConvention | None = None) -> None:
        self.link = link
        # The link's bus and target, so each access is one call less (every register
        # access of every driver comes through here).
        self._bus = link.bus
        self._target = link.target
        if convention is None:
            convention = (
                RegisterConvention.spi_read_bit7()
                if link.kind is BusKind.SPI
                else RegisterConvention.i2c()
            )
        self.convention = convention

    def read(self, register: int, length: int = 1) -> bytes:
        c = self.convention
        addr = register | c.read_set | (c.burst_set if length > 1 else c.single_set)
        return self._bus.transfer(self._target, bytes((addr & 0xFF,)), length)

    def read_address(self, register: int, length: int = 1) -> int:
        """The address byte a read of ``length`` bytes from ``register`` sends."""
        c = self.convention
        return (register | c.read_set | (c.burst_set if length > 1 else c.single_set)) & 0xFF

    def write_address(self, register: int) -> int:
        """The address byte a one-register write to ``register`` sends."""
        c = self.convention
        return ((register & ~c.write_clear) | c.single_set) & 0xFF

    def send(self, frame: bytes, read_len: int = 0) -> bytes:
        """One transaction of bytes prepared with :meth:`read_address` / :meth:`write_address`
        (for a sequence repeated many times, such as an I2C master's per-byte accesses)."""
        return self._bus.transfer(self._target, frame, read_len)

    def read_u8(self, register: int) -> int:
        return self.read(register, 1)[0]

    def write(self, register: int, data: bytes | int) -> None:
        c = self.convention
        if isinstance(data, int):
            # One register, the common case (configuration writes, every aux-master byte):
            # the same bytes as the general path below, built in one step.
            self._bus.transfer(self._target, bytes((((register & ~c.write_clear)
                                                     | c.single_set) & 0xFF, data)), 0)
            return
        payload = bytes(data)
        if c.pairwise_burst_write and len(payload) > 1:
            pairs = bytearray()
            for offset, value in enumerate(payload):
                pairs += bytes([((register + offset) & ~c.write_clear) & 0xFF, value])
            self.link.transfer(bytes(pairs), 0)
            return
        extra = c.burst_set if len(payload) > 1 else c.single_set
        addr = ((register & ~c.write_clear) | extra) & 0xFF
        self.link.transfer(bytes([addr]) + payload, 0)

    def update_bits(self, register: int, mask: int, value: int) -> None:
        """Read-modify-write the bits in ``mask``."""
        old = self.read_u8(register)
        self.write(register, (old & ~mask) | (value & mask))
