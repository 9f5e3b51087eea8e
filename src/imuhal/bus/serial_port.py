"""A serial link through pyserial (for sensor bridges that speak bytes over a UART)."""

from __future__ import annotations

from typing import Any, ClassVar

from pydantic import Field

from imuhal.bus.base import Bus, BusKind
from imuhal.bus.factory import BusFactory, BusSettings
from imuhal.core.errors import BusError


class SerialBus(Bus):
    """Target is ignored: a UART has one peer. A read shorter than asked is a timeout error.

    A write hands its bytes to the port's transmit buffer (the kernel's, kilobytes) and
    returns; the UART sends them at the line rate meanwhile. It does not wait for them to
    leave (``tcdrain``): 16 bytes take 17 ms at 9600 baud, more than three periods of a
    200 Hz IMU polled on the same thread. A read that follows waits for its answer anyway.
    """

    kind = BusKind.SERIAL

    def __init__(self, port: str, *, baudrate: int = 115200, timeout_s: float = 0.5,
                 serial_factory: Any | None = None) -> None:
        super().__init__(f"serial://{port}")
        if serial_factory is None:
            import serial

            serial_factory = serial.serial_for_url
        try:
            self._port = serial_factory(port, baudrate=baudrate, timeout=timeout_s)
        except Exception as exc:  # pyserial raises SerialException (an OSError subclass)
            raise BusError(
                f"cannot open {port}: {getattr(exc, 'strerror', None) or exc}. Is the UART "
                "enabled (Raspberry Pi: raspi-config, serial port on, login shell off), is the "
                "profile's bus `port` right, and are you in the 'dialout' group?",
                bus=self.name) from exc

    def _transfer(self, target: int, write: bytes, read_len: int) -> bytes:
        try:
            if write:
                self._port.write(write)
            data = self._port.read(read_len) if read_len else b""
        except Exception as exc:
            raise BusError(f"serial transfer failed: {exc}", bus=self.name) from exc
        if len(data) != read_len:
            raise BusError(f"timeout: read {len(data)} of {read_len} bytes", bus=self.name)
        return bytes(data)

    def _receive(self, target: int, max_len: int) -> bytes:
        try:
            waiting = self._port.in_waiting
            data = self._port.read(min(max_len, waiting)) if waiting else b""
        except Exception as exc:
            raise BusError(f"serial read failed: {exc}", bus=self.name) from exc
        return bytes(data)

    def set_baudrate(self, baudrate: int) -> None:
        """Change the line speed (a driver probing for a receiver's baud rate)."""
        try:
            self._port.baudrate = baudrate
            self._port.reset_input_buffer()
        except Exception as exc:
            raise BusError(f"cannot set {baudrate} baud: {exc}", bus=self.name) from exc

    def close(self) -> None:
        if self._port is not None:
            self._port.close()
            self._port = None


class SerialSettings(BusSettings):
    port: str
    """A device path or a pyserial URL (e.g. /dev/ttyUSB0, socket://127.0.0.1:7000)."""
    baudrate: int = Field(115200, gt=0)
    timeout_s: float = Field(0.5, gt=0)


class SerialFactory(BusFactory):
    scheme: ClassVar[str] = "serial"
    kind = BusKind.SERIAL
    Settings = SerialSettings
    description = "a UART through pyserial"

    @classmethod
    def open(cls, name: str, settings: BusSettings) -> Bus:
        assert isinstance(settings, SerialSettings)
        return SerialBus(settings.port, baudrate=settings.baudrate, timeout_s=settings.timeout_s)
