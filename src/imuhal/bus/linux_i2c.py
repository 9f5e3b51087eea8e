"""Linux I2C through i2c-dev and smbus2, in the best mode the adapter offers.

The kernel says which transfers an adapter supports (the I2C_FUNCS ioctl, which smbus2 reads
when it opens the device). Two modes follow from it:

* ``i2c_rdwr`` (the adapter has I2C_FUNC_I2C): each transaction is one combined I2C_RDWR
  message pair, a write then a read with repeated start, of any length.
* ``smbus`` (SMBus-only adapters: PC SMBus hosts, some SoC adapters, the kernel's i2c-stub,
  whose I2C_RDWR fails with EOPNOTSUPP): a register read ``[reg] -> n bytes`` is SMBus "read
  I2C block" transfers of at most 32 bytes, the k-th starting at register ``reg + 32 k``
  (what the chip's auto-increment would have reached; the pieces are separate transactions,
  so a chip that latches its data registers only within one read sees several reads);
  ``[reg, data...]`` is "write byte data" for one byte, "write I2C block" for more (in
  32-byte pieces), "send byte" for none; a read without a register is "receive byte" per
  byte. A transaction that needs a write and a read in one (a write of more than the register
  byte followed by a read) cannot be expressed in SMBus and is a BusError naming the mode.
  Adapters without block transfers but with byte data transfers read byte by byte.

:attr:`LinuxI2CBus.mode` holds the choice and :meth:`LinuxI2CBus.describe` names it; the run
summary lists it beside the bus. The profile's ``transfer_mode`` (``auto`` by default) can
force either: ``smbus`` on an adapter whose combined transfers a chip behind it mishandles,
``i2c_rdwr`` to see what an adapter does with them (an SMBus-only one refuses every transfer
with EOPNOTSUPP, a BusError naming the mode: how imuhal failed on such adapters before it
read I2C_FUNCS).
"""

from __future__ import annotations

import errno
from typing import Any, ClassVar, Literal

from smbus2 import I2cFunc, SMBus, i2c_msg

from imuhal.bus.base import Bus, BusKind
from imuhal.bus.factory import BusFactory, BusSettings
from imuhal.core.errors import BusError, NackError

SMBUS_BLOCK_MAX = 32
"""Largest SMBus (I2C) block transfer, bytes (I2C_SMBUS_BLOCK_MAX)."""

_NACK_ERRNOS = frozenset({errno.ENXIO, errno.EREMOTEIO, errno.ENODEV})
"""No acknowledge from the address: ENXIO and EREMOTEIO from I2C adapters
(Documentation/i2c/fault-codes.rst); ENODEV from SMBus-only adapters that know which
addresses exist, like i2c-stub."""

I2CMode = Literal["i2c_rdwr", "smbus"]


def choose_mode(funcs: int) -> I2CMode | None:
    """The transfer mode for an adapter's I2C_FUNCS bit mask, or None when it offers
    neither combined I2C messages nor SMBus register transfers."""
    if funcs & I2cFunc.I2C:
        return "i2c_rdwr"
    reads = I2cFunc.SMBUS_READ_I2C_BLOCK | I2cFunc.SMBUS_READ_BYTE_DATA
    writes = I2cFunc.SMBUS_WRITE_I2C_BLOCK | I2cFunc.SMBUS_WRITE_BYTE_DATA
    if funcs & reads and funcs & writes:
        return "smbus"
    return None


class LinuxI2CBus(Bus):
    kind = BusKind.I2C

    def __init__(self, device: str, *, smbus: Any | None = None,
                 mode: I2CMode | None = None) -> None:
        """Open ``device`` (``/dev/i2c-N``); ``mode`` None chooses the transfer mode from the
        adapter's I2C_FUNCS, a mode forces it (the kernel then refuses what the adapter
        lacks)."""
        super().__init__(f"i2c://{device}")
        self.device = device
        try:
            self._smbus = smbus if smbus is not None else SMBus(device)
        except OSError as exc:
            raise BusError(
                f"cannot open {device}: {exc.strerror or exc}. Is the I2C interface enabled "
                f"(raspi-config / dtparam=i2c_arm=on) and are you in the 'i2c' group?",
                bus=self.name,
            ) from exc
        self.funcs = int(self._smbus.funcs)
        """The adapter's I2C_FUNCS bit mask (linux/i2c.h I2C_FUNC_*)."""
        if mode is None:
            mode = choose_mode(self.funcs)
        if mode is None:
            self.close()
            raise BusError(f"{device} offers neither I2C messages nor SMBus register "
                           f"transfers (I2C_FUNCS 0x{self.funcs:08X}): not usable for chips",
                           bus=self.name)
        self.mode: I2CMode = mode
        self._block_reads = bool(self.funcs & I2cFunc.SMBUS_READ_I2C_BLOCK)
        self._block_writes = bool(self.funcs & I2cFunc.SMBUS_WRITE_I2C_BLOCK)

    def describe(self) -> str:
        if self.mode == "i2c_rdwr":
            lacking = "" if self.funcs & I2cFunc.I2C else (
                f", forced (the adapter lacks I2C_FUNC_I2C, I2C_FUNCS 0x{self.funcs:08X})")
            return f"{self.name}: I2C_RDWR combined transfers{lacking}"
        return (f"{self.name}: SMBus transfers (the adapter has no I2C_RDWR, I2C_FUNCS "
                f"0x{self.funcs:08X}); register reads in {SMBUS_BLOCK_MAX}-byte pieces")

    def _transfer(self, target: int, write: bytes, read_len: int) -> bytes:
        if not write and not read_len:
            return b""
        try:
            if self.mode == "i2c_rdwr":
                return self._rdwr(target, write, read_len)
            return self._smbus_transfer(target, write, read_len)
        except OSError as exc:
            if exc.errno in _NACK_ERRNOS:
                raise NackError(f"no ACK from address 0x{target:02X} ({exc.strerror})",
                                bus=self.name, target=target) from exc
            raise BusError(f"I2C transfer failed ({self.mode}): {exc}", bus=self.name,
                           target=target) from exc

    def _rdwr(self, target: int, write: bytes, read_len: int) -> bytes:
        msgs = []
        if write:
            msgs.append(i2c_msg.write(target, write))
        read_msg = i2c_msg.read(target, read_len) if read_len else None
        if read_msg is not None:
            msgs.append(read_msg)
        self._smbus.i2c_rdwr(*msgs)
        return bytes(read_msg) if read_msg is not None else b""

    def _smbus_transfer(self, target: int, write: bytes, read_len: int) -> bytes:
        bus = self._smbus
        if not read_len:
            register, data = write[0], write[1:]
            if not data:
                bus.write_byte(target, register)
            elif len(data) == 1:
                bus.write_byte_data(target, register, data[0])
            elif self._block_writes:
                for start in range(0, len(data), SMBUS_BLOCK_MAX):
                    bus.write_i2c_block_data(target, (register + start) & 0xFF,
                                             list(data[start:start + SMBUS_BLOCK_MAX]))
            else:
                for i, value in enumerate(data):
                    bus.write_byte_data(target, (register + i) & 0xFF, value)
            return b""
        if not write:
            return bytes(bus.read_byte(target) for _ in range(read_len))
        if len(write) > 1:
            raise BusError(f"a {len(write)}-byte write followed by a read needs I2C_RDWR, "
                           "which this SMBus-only adapter lacks", bus=self.name, target=target)
        register = write[0]
        if not self._block_reads:
            return bytes(bus.read_byte_data(target, (register + i) & 0xFF)
                         for i in range(read_len))
        out = bytearray()
        while len(out) < read_len:
            size = min(SMBUS_BLOCK_MAX, read_len - len(out))
            piece = bytes(bus.read_i2c_block_data(target, (register + len(out)) & 0xFF, size))
            if len(piece) != size:
                raise BusError(f"SMBus block read returned {len(piece)} of {size} bytes",
                               bus=self.name, target=target)
            out += piece
        return bytes(out)

    def close(self) -> None:
        if self._smbus is not None:
            self._smbus.close()
            self._smbus = None


class I2CSettings(BusSettings):
    device: str = "/dev/i2c-1"
    """The i2c-dev character device."""
    transfer_mode: Literal["auto", "i2c_rdwr", "smbus"] = "auto"
    """``auto``: I2C_RDWR where the adapter's I2C_FUNCS has I2C_FUNC_I2C, SMBus transfers
    where it is SMBus-only; ``i2c_rdwr`` or ``smbus`` forces one (see the module's notes)."""


class LinuxI2CFactory(BusFactory):
    scheme: ClassVar[str] = "i2c"
    kind = BusKind.I2C
    Settings = I2CSettings
    description = ("Linux i2c-dev through smbus2: I2C_RDWR where the adapter has it, SMBus "
                   "transfers where it is SMBus-only")

    @classmethod
    def open(cls, name: str, settings: BusSettings) -> Bus:
        assert isinstance(settings, I2CSettings)
        mode = None if settings.transfer_mode == "auto" else settings.transfer_mode
        return LinuxI2CBus(settings.device, mode=mode)
