"""Linux SPI through spidev. Target = chip select: /dev/spidev<bus>.<cs>."""

from __future__ import annotations

import importlib
from typing import Any, ClassVar, Literal

from pydantic import Field

from imuhal.bus.base import Bus, BusKind
from imuhal.bus.factory import BusFactory, BusSettings
from imuhal.core.errors import BusError


class LinuxSPIBus(Bus):
    kind = BusKind.SPI

    def __init__(self, bus: int, *, mode: int = 3, max_speed_hz: int = 1_000_000,
                 spidev_module: Any | None = None) -> None:
        super().__init__(f"spi:///dev/spidev{bus}")
        self.bus_number = bus
        self.mode = mode
        self.max_speed_hz = max_speed_hz
        self._spidev = spidev_module
        self._devices: dict[int, Any] = {}

    def _module(self) -> Any:
        if self._spidev is None:
            try:
                self._spidev = importlib.import_module("spidev")
            except ImportError as exc:
                raise BusError("the spidev package is not installed (Linux only): "
                               "pip install spidev", bus=self.name) from exc
        return self._spidev

    def _device(self, cs: int) -> Any:
        dev = self._devices.get(cs)
        if dev is None:
            dev = self._module().SpiDev()
            try:
                dev.open(self.bus_number, cs)
            except OSError as exc:
                raise BusError(
                    f"cannot open /dev/spidev{self.bus_number}.{cs}: {exc.strerror or exc}. "
                    "Is SPI enabled (dtparam=spi=on) and does that chip select exist?",
                    bus=self.name, target=cs,
                ) from exc
            dev.mode = self.mode
            dev.max_speed_hz = self.max_speed_hz
            self._devices[cs] = dev
        return dev

    def _transfer(self, target: int, write: bytes, read_len: int) -> bytes:
        dev = self._device(target)
        try:
            rx = dev.xfer2(list(write) + [0] * read_len)
        except OSError as exc:
            raise BusError(f"SPI transfer failed: {exc}", bus=self.name, target=target) from exc
        return bytes(rx[len(write):])

    def close(self) -> None:
        for dev in self._devices.values():
            dev.close()
        self._devices.clear()


class SPISettings(BusSettings):
    bus: int = Field(0, ge=0)
    """N in /dev/spidevN.CS."""
    mode: Literal[0, 1, 2, 3] = 3
    max_speed_hz: int = Field(1_000_000, gt=0, le=50_000_000)


class LinuxSPIFactory(BusFactory):
    scheme: ClassVar[str] = "spi"
    kind = BusKind.SPI
    Settings = SPISettings
    description = "Linux spidev; devices name their chip select as address"

    @classmethod
    def open(cls, name: str, settings: BusSettings) -> Bus:
        assert isinstance(settings, SPISettings)
        return LinuxSPIBus(settings.bus, mode=settings.mode, max_speed_hz=settings.max_speed_hz)
