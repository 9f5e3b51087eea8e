"""The Linux SPI backend, tested at the spidev boundary with a fake module."""

from __future__ import annotations

from typing import ClassVar

import pytest

from imuhal.bus.linux_spi import LinuxSPIBus
from imuhal.core.errors import BusError


class FakeSpiDev:
    opened: ClassVar[list[tuple[int, int]]] = []

    def __init__(self) -> None:
        self.mode = 0
        self.max_speed_hz = 0
        self.sent: list[list[int]] = []

    def open(self, bus: int, cs: int) -> None:
        if cs > 1:
            raise OSError(2, "No such file or directory")
        FakeSpiDev.opened.append((bus, cs))

    def xfer2(self, data: list[int]) -> list[int]:
        self.sent.append(list(data))
        return [0xFF] + [i & 0xFF for i in range(1, len(data))]

    def close(self) -> None:
        pass


class FakeModule:
    SpiDev = FakeSpiDev


def test_a_transfer_clocks_write_then_dummy_bytes_and_returns_the_read_part() -> None:
    bus = LinuxSPIBus(0, mode=3, max_speed_hz=2_000_000, spidev_module=FakeModule)
    assert bus.transfer(1, b"\xa0", 2) == bytes([1, 2])
    dev = bus._devices[1]
    assert dev.sent == [[0xA0, 0, 0]]
    assert (dev.mode, dev.max_speed_hz) == (3, 2_000_000)


def test_each_chip_select_opens_its_own_device_file_once() -> None:
    FakeSpiDev.opened = []
    bus = LinuxSPIBus(0, spidev_module=FakeModule)
    bus.transfer(0, b"\x00", 1)
    bus.transfer(0, b"\x00", 1)
    bus.transfer(1, b"\x00", 1)
    assert FakeSpiDev.opened == [(0, 0), (0, 1)]


def test_a_missing_chip_select_is_reported_with_its_device_path() -> None:
    bus = LinuxSPIBus(0, spidev_module=FakeModule)
    with pytest.raises(BusError, match=r"/dev/spidev0\.5"):
        bus.transfer(5, b"\x00", 1)
