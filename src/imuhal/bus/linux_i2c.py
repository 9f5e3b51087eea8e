"""Linux I2C through smbus2's ``i2c_rdwr``: one combined transaction with repeated start and
no 32-byte SMBus block limit."""

from __future__ import annotations

from typing import Any, ClassVar

from smbus2 import SMBus, i2c_msg

from imuhal.bus.base import Bus, BusKind
from imuhal.bus.factory import BusFactory, BusSettings
from imuhal.core.errors import BusError, NackError

_ENXIO = 6
_EREMOTEIO = 121


class LinuxI2CBus(Bus):
    kind = BusKind.I2C

    def __init__(self, device: str, *, smbus: Any | None = None) -> None:
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

    def _transfer(self, target: int, write: bytes, read_len: int) -> bytes:
        msgs = []
        if write:
            msgs.append(i2c_msg.write(target, write))
        read_msg = i2c_msg.read(target, read_len) if read_len else None
        if read_msg is not None:
            msgs.append(read_msg)
        if not msgs:
            return b""
        try:
            self._smbus.i2c_rdwr(*msgs)
        except OSError as exc:
            if exc.errno in (_ENXIO, _EREMOTEIO):
                raise NackError(f"no ACK from address 0x{target:02X} ({exc.strerror})",
                                bus=self.name, target=target) from exc
            raise BusError(f"I2C transfer failed: {exc}", bus=self.name, target=target) from exc
        return bytes(read_msg) if read_msg is not None else b""

    def close(self) -> None:
        if self._smbus is not None:
            self._smbus.close()
            self._smbus = None


class I2CSettings(BusSettings):
    device: str = "/dev/i2c-1"
    """The i2c-dev character device."""


class LinuxI2CFactory(BusFactory):
    scheme: ClassVar[str] = "i2c"
    kind = BusKind.I2C
    Settings = I2CSettings
    description = "Linux i2c-dev through smbus2 i2c_rdwr"

    @classmethod
    def open(cls, name: str, settings: BusSettings) -> Bus:
        assert isinstance(settings, I2CSettings)
        return LinuxI2CBus(settings.device)
