"""Register address-byte conventions applied declaratively by RegisterView."""

from __future__ import annotations

from imuhal.bus.base import Bus, BusKind
from imuhal.bus.registers import RegisterConvention, RegisterView


class RecordingBus(Bus):
    def __init__(self, kind: BusKind) -> None:
        super().__init__("rec")
        self.kind = kind
        self.log: list[tuple[int, bytes, int]] = []

    def _transfer(self, target: int, write: bytes, read_len: int) -> bytes:
        self.log.append((target, write, read_len))
        return bytes(read_len)


def test_spi_reads_set_bit7_by_default() -> None:
    bus = RecordingBus(BusKind.SPI)
    RegisterView(bus.link(0)).read(0x75, 1)
    assert bus.log == [(0, b"\xf5", 1)]


def test_i2c_reads_send_the_plain_register() -> None:
    bus = RecordingBus(BusKind.I2C)
    RegisterView(bus.link(0x68)).read(0x3B, 14)
    assert bus.log == [(0x68, b"\x3b", 14)]


def test_max2110x_style_single_access_sets_the_no_increment_bit() -> None:
    bus = RecordingBus(BusKind.SPI)
    view = RegisterView(bus.link(1), RegisterConvention(read_set=0x80, single_set=0x40))
    view.read(0x20, 1)
    view.read(0x24, 6)
    assert [w for _, w, _ in bus.log] == [b"\xe0", b"\xa4"]


def test_bmp280_style_spi_writes_clear_bit7_in_address_data_pairs() -> None:
    bus = RecordingBus(BusKind.SPI)
    view = RegisterView(bus.link(0), RegisterConvention(read_set=0x80, write_clear=0x80,
                                                       pairwise_burst_write=True))
    view.write(0xF4, bytes([0x27, 0xA0]))
    assert bus.log == [(0, bytes([0x74, 0x27, 0x75, 0xA0]), 0)]


def test_update_bits_changes_only_the_masked_bits() -> None:
    class Mem(RecordingBus):
        def _transfer(self, target: int, write: bytes, read_len: int) -> bytes:
            super()._transfer(target, write, read_len)
            return b"\xf0" if read_len else b""

    bus = Mem(BusKind.I2C)
    RegisterView(bus.link(0x1E)).update_bits(0x00, 0x0F, 0x05)
    assert bus.log[-1] == (0x1E, b"\x00\xf5", 0)
