"""The MAX21100's I2C master as a Bus, so unchanged I2C drivers (HMC5883L) run behind it.

Mechanism [SS: har-in-air ESP32_IMU_BARO_GPS_LOGGER max21100.c, real hardware; see
facts/chips.md section 6]: the master does one-byte *one-shot* transactions with the slave
whose 7-bit address is in MAG_SLV_ADD (0x08):

- write: I2C_MST_ADD (0x0B) <- register, I2C_MST_DATA (0x0C) <- value,
  DR_CFG (0x13) <- base | 0x10 (trigger), DR_CFG <- base;
- read:  I2C_MST_ADD <- register, DR_CFG <- base | 0x30, DR_CFG <- base, wait,
  then read I2C_MST_DATA.

``base`` is the DR_CFG value the MAX21100 driver configured, so the trigger never changes
its data-ready or temperature settings.

How an I2C transaction maps onto one-shot bytes:
- ``write=[reg, d0, d1, ...]``: one one-shot write per byte, to reg, reg+1, ...: what a
  slave with an auto-incrementing register pointer would do with the burst write.
- ``write=[reg]`` + ``read_len=n``: one one-shot read per byte from reg, reg+1, ...: the
  same bytes a pointer that auto-increments linearly would return. A slave whose pointer
  wraps (HMC5883L: after register 8 back to 3) differs only for reads that cross the wrap,
  which no driver does. Coherence across the n separate reads is the slave's business:
  the HMC5883L locks its data outputs from the first data byte read until all six are read.
- ``write=[reg]`` alone sets a remembered pointer; a read with no register byte continues
  from it. The master cannot do a bare read without a register, so the pointer is emulated.
- A host transfer that fails during a one-shot byte repeats that byte (ONESHOT_ATTEMPTS),
  so the slave's driver sees about the host's error rate per transaction, not 28 times it.
- The master reports no NACK that any source documents; a missing slave shows as 0xFF data
  (released bus), which the slave's driver turns into DeviceNotFoundError when probing.

The whole sequence holds the parent bus lock, so the MAX21100 driver's own accesses never
interleave with a half-done one-shot transaction.

Slave auto-read (imuhal.bus.auto_read): ``auto_read(target, register, length)`` has the
MAX21100 itself read the slave at every accelerometer measurement into MAG X/Y/Z, which the
host's 21-byte burst carries anyway (facts section 6, steps 4-5); the MAX21100 driver
programs it and delivers the bytes of each burst to the returned feed (read from its FIFO,
the bytes of a small read of MAG X/Y/Z a guard after each measurement: the FIFO does not
hold them). One-shot transactions
still work beside it (the slave's driver configures and checks its chip with them); since
both use MAG_SLV_ADD, a one-shot transaction with another slave puts the auto-read's address
back when it ends.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TypeVar

from imuhal.bus.auto_read import AutoReadFeed
from imuhal.bus.base import Bus, BusKind
from imuhal.bus.registers import RegisterView
from imuhal.bus.retry import retried
from imuhal.core.clock import Clock
from imuhal.core.errors import BusError, ConfigurationError, NackError
from imuhal_chips.max2110x.registers import (
    DR_CFG_ONESHOT_MASK,
    DR_CFG_ONESHOT_READ,
    DR_CFG_ONESHOT_WRITE,
    Reg,
)

ONESHOT_WAIT_S = 200e-6
"""Time allowed for one one-shot byte transaction to finish (about 4 bytes at 400 kHz plus
margin) before the next step. [UNVERIFIED: har-in-air waits an unspecified delay.]"""
ONESHOT_ATTEMPTS = 3
"""Tries of one one-shot byte before a host bus error is passed on to the slave's driver."""

_R = TypeVar("_R")

# Plain ints: every slave byte writes these (an IntEnum member lookup costs more than the
# register access around it).
_MAG_SLV_ADD = int(Reg.MAG_SLV_ADD)
_I2C_MST_ADD = int(Reg.I2C_MST_ADD)
_I2C_MST_DATA = int(Reg.I2C_MST_DATA)
_DR_CFG = int(Reg.DR_CFG)


class Max21100AuxBus(Bus):
    """An I2C bus whose transfers are carried out by a MAX21100's one-shot master.

    It is handed a narrow port to its host, like the MPU-9250's aux bus: the MAX21100's
    registers (``regs``) and clock, the DR_CFG value the host configured (``dr_cfg``, read at
    each transfer: a reconfiguration may change it) and the host's ``enable_auto_read``."""

    kind = BusKind.I2C

    def __init__(self, name: str, regs: RegisterView, clock: Clock, *,
                 dr_cfg: Callable[[], int],
                 enable_auto_read: Callable[[int, int, int], AutoReadFeed]) -> None:
        super().__init__(name)
        self.regs = regs
        self.clock = clock
        self._dr_cfg = dr_cfg
        self._enable_auto_read = enable_auto_read
        self._feed: AutoReadFeed | None = None
        self._pointer: dict[int, int] = {}
        self._frames: dict[int, tuple[int, bytes, bytes, bytes]] = {}
        # Share the parent's lock: a one-shot sequence is several parent transfers.
        self.lock = regs.link.bus.lock

    def _base(self) -> int:
        return self._dr_cfg() & ~DR_CFG_ONESHOT_MASK

    def _transfer(self, target: int, write: bytes, read_len: int) -> bytes:
        if not 0 <= target <= 0x7F:
            raise ConfigurationError(f"{self.name}: 0x{target:X} is not a 7-bit I2C address")
        with self.lock:
            self._retried(self._select, target)
            if write:
                self._pointer[target] = write[0]
            pointer = self._pointer.get(target, 0)
            # The driver's DR_CFG cannot change during the sequence (the bus lock is held).
            base = self._base()
            for offset, value in enumerate(write[1:]):
                self._retried(self._oneshot_write, (pointer + offset) & 0xFF, value, base)
            if len(write) > 1:
                pointer = (pointer + len(write) - 1) & 0xFF
                self._pointer[target] = pointer
            data = bytearray()
            read = self._oneshot_read
            frames = self._read_frames(base) if read_len else None
            for offset in range(read_len):
                register = (pointer + offset) & 0xFF
                # retried() written out for the one step run once per slave byte read
                for attempt in range(ONESHOT_ATTEMPTS, 0, -1):
                    try:
                        data.append(read(register, frames))  # type: ignore[arg-type]  # frames is read whenever read_len > 0, which this loop needs
                        break
                    except NackError:
                        raise
                    except BusError:
                        if attempt == 1:
                            raise
            if read_len:
                self._pointer[target] = (pointer + read_len) & 0xFF
            feed = self._feed
            if feed is not None and feed.target != target:
                self._retried(self._select, feed.target)
        return bytes(data)

    def auto_read(self, target: int, register: int, length: int) -> AutoReadFeed:
        """Have the MAX21100 read ``length`` bytes (1..6) from ``register`` of ``target`` at
        every accelerometer measurement (see the module docstring)."""
        if not 0 <= target <= 0x7F:
            raise ConfigurationError(f"{self.name}: 0x{target:X} is not a 7-bit I2C address")
        with self.lock:
            self._feed = self._enable_auto_read(target, register, length)
            return self._feed

    def _retried(self, step: Callable[..., _R], *args: int) -> _R:
        """One one-shot byte (four host transfers), repeated after a failed host transfer;
        each step is safe to repeat (it rewrites the same address, data and trigger)."""
        return retried(step, *args, attempts=ONESHOT_ATTEMPTS)

    def _select(self, target: int) -> None:
        self.regs.write(_MAG_SLV_ADD, target)

    def _oneshot_write(self, register: int, value: int, base: int) -> None:
        regs = self.regs
        regs.write(_I2C_MST_ADD, bytes([register, value]))  # 0x0B, 0x0C auto-increment
        regs.write(_DR_CFG, base | DR_CFG_ONESHOT_WRITE)
        regs.write(_DR_CFG, base)
        self.clock.sleep(ONESHOT_WAIT_S)

    def _read_frames(self, base: int) -> tuple[int, bytes, bytes, bytes]:
        """What a one-shot read sends besides the slave register: the I2C_MST_ADD address
        byte, the DR_CFG trigger and restore writes, the I2C_MST_DATA read (formed by the
        host's register convention once per ``base``, not at every slave byte)."""
        frames = self._frames.get(base)
        if frames is None:
            regs = self.regs
            cfg = regs.write_address(_DR_CFG)
            frames = (regs.write_address(_I2C_MST_ADD),
                      bytes((cfg, base | DR_CFG_ONESHOT_READ)), bytes((cfg, base)),
                      bytes((regs.read_address(_I2C_MST_DATA, 1),)))
            self._frames[base] = frames
        return frames

    def _oneshot_read(self, register: int, frames: tuple[int, bytes, bytes, bytes]) -> int:
        """I2C_MST_ADD <- register, DR_CFG <- base | read trigger, DR_CFG <- base, wait,
        then read I2C_MST_DATA: the same transfers as through ``regs.write``/``regs.read``."""
        send = self.regs.send
        address, trigger, restore, read_data = frames
        send(bytes((address, register)))
        send(trigger)
        send(restore)
        self.clock.sleep(ONESHOT_WAIT_S)
        return send(read_data, 1)[0]
