"""The MPU-9250's auxiliary I2C bus as an imuhal Bus, so the AK8963 driver runs unchanged.

Two ways to reach chips on the auxiliary bus (the AK8963 at 0x0C on every MPU-9250):

- **bypass** (MPU on I2C only): USER_CTRL.I2C_MST_EN = 0 and INT_PIN_CFG.BYPASS_EN = 1 join
  the auxiliary pins to the host bus. The aux bus is then simply the host I2C bus.
- **master** (MPU on I2C or SPI): :class:`MasterAuxBus` performs each transfer through the
  MPU's internal I2C master, slave 4, one byte per transaction (I2C_SLV4_ADDR/REG/DO/CTRL,
  then I2C_MST_STATUS.SLV4_DONE/SLV4_NACK, then I2C_SLV4_DI).

How one aux transfer maps to master transactions: ``write = [reg, d0, d1, ...]`` becomes
single-byte writes d0 -> reg, d1 -> reg + 1, ...; ``write = [reg]`` with ``read_len = n``
becomes n single-byte reads of reg, reg + 1, ..., reg + n - 1. That is what one
auto-incrementing I2C transfer does on chips whose register pointer simply counts up over
the range read (the AK8963 does, within 0x00..0x0C and 0x10..0x12). The n bytes are *not*
one I2C transaction on the wire: the AK8963 keeps them coherent by itself (data read starts
protection, reading ST2 last ends it), which is why its driver always ends a burst at ST2.
Cost: per byte one 4-byte register write and at least two reads of the MPU (status, DI).

Slave auto-read (imuhal.bus.auto_read): in master mode :meth:`MasterAuxBus.auto_read` has
slave 0 read the slave at every MPU sample into EXT_SENS_DATA (I2C_SLV0_ADDR/REG/CTRL, the
Linux ``inv_mpu6050`` recipe, facts section 4); the MPU-9250 driver reads those bytes in the
same burst as accel and gyro and delivers them to the feed. Slave-4 transactions keep
working beside it (the slave's driver configures and checks its chip with them).
"""

from __future__ import annotations

from collections.abc import Callable

from imuhal.bus.auto_read import AutoReadFeed
from imuhal.bus.base import Bus, BusKind
from imuhal.bus.registers import RegisterView
from imuhal.bus.retry import retried
from imuhal.core.clock import Clock
from imuhal.core.errors import BusError, ConfigurationError, NackError
from imuhal_chips.mpu9250 import registers as r

SLV4_POLL_S = 50e-6
"""Interval between I2C_MST_STATUS polls; a 400 kHz single-byte read takes ~100 us."""
SLV4_TIMEOUT_S = 5e-3
SLV4_ATTEMPTS = 3
"""Tries of one slave-4 byte before a host bus error reaches the slave's driver: a slave
byte costs three or more host transfers, whose error rate must not be multiplied."""


class MasterAuxBus(Bus):
    """An I2C bus whose transfers run on the MPU-9250's internal I2C master (slave 4)."""

    kind = BusKind.I2C

    def __init__(self, name: str, mpu: RegisterView, clock: Clock,
                 enable_auto_read: Callable[[int, int, int], AutoReadFeed]) -> None:
        super().__init__(name)
        self.mpu = mpu
        self.clock = clock
        self._enable_auto_read = enable_auto_read
        self.slv0_nack = False
        """I2C_MST_STATUS.SLV0_NACK was set in a status read here (it clears when read):
        slave 0's auto-read of a sample failed; the MPU-9250 driver takes it over."""

    def auto_read(self, target: int, register: int, length: int) -> AutoReadFeed:
        """Have slave 0 read ``length`` bytes from ``register`` of ``target`` at every MPU
        sample (see the module docstring)."""
        if not 0 <= target <= 0x7F:
            raise ConfigurationError(f"{self.name}: 0x{target:X} is not a 7-bit I2C address")
        with self.mpu.link.bus.lock:
            return self._enable_auto_read(target, register, length)

    def _transfer(self, target: int, write: bytes, read_len: int) -> bytes:
        if not write:
            raise BusError("the MPU-9250 I2C master needs a register address to read from",
                           bus=self.name, target=target)
        # Hold the host bus for the whole sequence so no other driver's access interleaves.
        with self.mpu.link.bus.lock:
            register = write[0]
            for offset, value in enumerate(write[1:]):
                retried(self._slv4, target, (register + offset) & 0xFF, value,
                        attempts=SLV4_ATTEMPTS)
            return bytes(retried(self._slv4, target, (register + i) & 0xFF,
                                 attempts=SLV4_ATTEMPTS) for i in range(read_len))

    def _slv4(self, target: int, register: int, value: int | None = None) -> int:
        """One slave-4 transaction: write ``value`` (or read when None); returns DI."""
        address = (target & 0x7F) | (r.SLV_READ if value is None else 0)
        # SLV4_ADDR, SLV4_REG, SLV4_DO, SLV4_CTRL are consecutive: one burst write, EN last.
        self.mpu.write(r.I2C_SLV4_ADDR, bytes([address, register, value or 0, r.SLV_EN]))
        deadline = self.clock.now_ns() + round(SLV4_TIMEOUT_S * 1e9)
        while True:
            status = self.mpu.read_u8(r.I2C_MST_STATUS)  # clears on read
            if status & r.MST_SLV0_NACK:
                self.slv0_nack = True
            if status & r.MST_SLV4_NACK:
                raise NackError(f"no device answered at address 0x{target:02X} "
                                "(via the MPU-9250 I2C master)", bus=self.name, target=target)
            if status & r.MST_SLV4_DONE:
                # DI is read after DONE, never in the same burst: DONE guarantees DI is written.
                return self.mpu.read_u8(r.I2C_SLV4_DI) if value is None else 0
            if self.clock.now_ns() > deadline:
                raise BusError(
                    f"MPU-9250 I2C master did not finish a transaction with 0x{target:02X} in "
                    f"{SLV4_TIMEOUT_S * 1e3:g} ms (is I2C_MST_EN set and the MPU awake?)",
                    bus=self.name, target=target)
            self.clock.sleep(SLV4_POLL_S)
