"""The Linux I2C backend, tested at smbus2's i2c_rdwr boundary with a fake adapter."""

from __future__ import annotations

import errno

import pytest

from imuhal.bus.linux_i2c import LinuxI2CBus
from imuhal.core.errors import BusError, NackError


class FakeSMBus:
    """Stands in for smbus2.SMBus: records messages, fills reads from a register array."""

    def __init__(self, fail_errno: int | None = None) -> None:
        self.memory = bytes(range(256))
        self.calls: list[list[tuple[str, int, bytes]]] = []
        self.fail_errno = fail_errno
        self.closed = False

    def i2c_rdwr(self, *msgs) -> None:  # type: ignore[no-untyped-def]
        if self.fail_errno is not None:
            raise OSError(self.fail_errno, "fake failure")
        record = []
        pointer = 0
        for m in msgs:
            if m.flags & 1:  # I2C_M_RD
                data = self.memory[pointer:pointer + m.len]
                for i, b in enumerate(data):
                    m.buf[i] = b
                record.append(("read", m.addr, bytes(data)))
            else:
                written = bytes(m)
                pointer = written[0] if written else 0
                record.append(("write", m.addr, written))
        self.calls.append(record)

    def close(self) -> None:
        self.closed = True


def test_a_register_read_is_one_combined_write_then_read_transaction() -> None:
    fake = FakeSMBus()
    bus = LinuxI2CBus("/dev/i2c-1", smbus=fake)
    assert bus.transfer(0x77, b"\x10", 3) == bytes([0x10, 0x11, 0x12])
    assert fake.calls == [[("write", 0x77, b"\x10"), ("read", 0x77, bytes([0x10, 0x11, 0x12]))]]


def test_reads_longer_than_the_smbus_32_byte_block_limit_work() -> None:
    bus = LinuxI2CBus("/dev/i2c-1", smbus=FakeSMBus())
    assert bus.transfer(0x68, b"\x00", 64) == bytes(range(64))


def test_a_write_only_transfer_sends_no_read_message() -> None:
    fake = FakeSMBus()
    LinuxI2CBus("/dev/i2c-1", smbus=fake).transfer(0x1E, b"\x02\x00", 0)
    assert fake.calls == [[("write", 0x1E, b"\x02\x00")]]


@pytest.mark.parametrize("code", [errno.ENXIO, errno.EREMOTEIO])
def test_no_acknowledge_becomes_a_nack_error_naming_the_address(code: int) -> None:
    bus = LinuxI2CBus("/dev/i2c-1", smbus=FakeSMBus(fail_errno=code))
    with pytest.raises(NackError, match="0x77"):
        bus.transfer(0x77, b"\x00", 1)


def test_other_io_errors_become_bus_errors() -> None:
    bus = LinuxI2CBus("/dev/i2c-1", smbus=FakeSMBus(fail_errno=errno.EIO))
    with pytest.raises(BusError, match="i2c:///dev/i2c-1"):
        bus.transfer(0x77, b"\x00", 1)


def test_a_missing_adapter_is_reported_with_a_hint() -> None:
    with pytest.raises(BusError, match="I2C interface enabled"):
        LinuxI2CBus("/dev/i2c-does-not-exist")


def test_close_releases_the_adapter() -> None:
    fake = FakeSMBus()
    LinuxI2CBus("/dev/i2c-1", smbus=fake).close()
    assert fake.closed
