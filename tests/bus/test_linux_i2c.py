"""The Linux I2C backend, tested at smbus2's boundary with fake adapters: a full I2C adapter
(I2C_RDWR) and an SMBus-only one (the kernel's i2c-stub and PC SMBus hosts; the same code runs
against the real i2c-stub in tests/kernel/test_i2c.py)."""

from __future__ import annotations

import errno

import pytest
from smbus2 import I2cFunc

from imuhal.bus.linux_i2c import SMBUS_BLOCK_MAX, LinuxI2CBus, choose_mode
from imuhal.core.clock import SimulatedClock
from imuhal.core.errors import BusError, NackError, ProfileError
from imuhal.pipeline import HardwareBoard, Pipeline
from imuhal.plugins.manager import load_registry
from imuhal.profile.loader import parse_profile


class FakeSMBus:
    """Stands in for smbus2.SMBus: records messages, fills reads from a register array."""

    funcs = int(I2cFunc.I2C | I2cFunc.SMBUS_QUICK)

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


I2C_STUB_FUNCS = 0x0C7F0000
"""I2C_FUNCS of the kernel's i2c-stub as measured in a guest: SMBus transfers, no I2C."""


class FakeSMBusOnly:
    """An SMBus-only adapter: a 256-byte register file behind SMBus transfers; i2c_rdwr
    fails with EOPNOTSUPP as the kernel's does. Records each SMBus call."""

    def __init__(self, funcs: int = I2C_STUB_FUNCS, present: int = 0x68) -> None:
        self.funcs = funcs
        self.present = present
        self.memory = bytearray(range(256))
        self.calls: list[tuple] = []

    def _check(self, addr: int) -> None:
        if addr != self.present:
            raise OSError(errno.ENODEV, "No such device")

    def i2c_rdwr(self, *msgs) -> None:  # type: ignore[no-untyped-def]
        raise OSError(errno.EOPNOTSUPP, "Operation not supported")

    def read_i2c_block_data(self, addr: int, reg: int, length: int) -> list[int]:
        self._check(addr)
        assert length <= SMBUS_BLOCK_MAX
        self.calls.append(("read_i2c_block", reg, length))
        return list(self.memory[reg:reg + length])

    def read_byte_data(self, addr: int, reg: int) -> int:
        self._check(addr)
        self.calls.append(("read_byte_data", reg))
        return self.memory[reg]

    def write_i2c_block_data(self, addr: int, reg: int, data: list[int]) -> None:
        self._check(addr)
        assert len(data) <= SMBUS_BLOCK_MAX
        self.calls.append(("write_i2c_block", reg, bytes(data)))
        self.memory[reg:reg + len(data)] = bytes(data)

    def write_byte_data(self, addr: int, reg: int, value: int) -> None:
        self._check(addr)
        self.calls.append(("write_byte_data", reg, value))
        self.memory[reg] = value

    def write_byte(self, addr: int, value: int) -> None:
        self._check(addr)
        self.calls.append(("write_byte", value))

    def close(self) -> None:
        pass


def test_an_adapter_with_plain_i2c_uses_combined_transfers() -> None:
    assert choose_mode(int(I2cFunc.I2C)) == "i2c_rdwr"
    assert LinuxI2CBus("/dev/i2c-1", smbus=FakeSMBus()).mode == "i2c_rdwr"


def test_an_smbus_only_adapter_uses_smbus_transfers() -> None:
    assert choose_mode(I2C_STUB_FUNCS) == "smbus"
    bus = LinuxI2CBus("/dev/i2c-0", smbus=FakeSMBusOnly())
    assert bus.mode == "smbus"
    assert "SMBus transfers" in bus.describe() and "0x0C7F0000" in bus.describe()


def test_an_adapter_without_register_transfers_is_refused_naming_its_functions() -> None:
    with pytest.raises(BusError, match="I2C_FUNCS 0x00010000"):
        LinuxI2CBus("/dev/i2c-9", smbus=FakeSMBusOnly(funcs=int(I2cFunc.SMBUS_QUICK)))


def test_smbus_register_reads_go_in_32_byte_pieces_from_the_advancing_register() -> None:
    fake = FakeSMBusOnly()
    bus = LinuxI2CBus("/dev/i2c-0", smbus=fake)
    assert bus.transfer(0x68, b"\x10", 70) == bytes(range(0x10, 0x10 + 70))
    assert fake.calls == [("read_i2c_block", 0x10, 32), ("read_i2c_block", 0x30, 32),
                          ("read_i2c_block", 0x50, 6)]


def test_smbus_writes_use_byte_data_for_one_byte_and_i2c_block_for_more() -> None:
    fake = FakeSMBusOnly()
    bus = LinuxI2CBus("/dev/i2c-0", smbus=fake)
    bus.transfer(0x68, b"\x6b\x80")
    bus.transfer(0x68, b"\x19" + bytes(range(40)))
    assert fake.calls == [("write_byte_data", 0x6B, 0x80),
                          ("write_i2c_block", 0x19, bytes(range(32))),
                          ("write_i2c_block", 0x39, bytes(range(32, 40)))]
    assert fake.memory[0x19:0x19 + 40] == bytes(range(40))


def test_without_block_transfers_smbus_reads_go_byte_by_byte() -> None:
    funcs = int(I2cFunc.SMBUS_READ_BYTE_DATA | I2cFunc.SMBUS_WRITE_BYTE_DATA)
    fake = FakeSMBusOnly(funcs=funcs)
    assert LinuxI2CBus("/dev/i2c-0", smbus=fake).transfer(0x68, b"\x3b", 3) == b"\x3b\x3c\x3d"
    assert fake.calls == [("read_byte_data", 0x3B), ("read_byte_data", 0x3C),
                          ("read_byte_data", 0x3D)]


def test_a_write_then_read_smbus_cannot_express_is_a_bus_error_naming_i2c_rdwr() -> None:
    bus = LinuxI2CBus("/dev/i2c-0", smbus=FakeSMBusOnly())
    with pytest.raises(BusError, match="needs I2C_RDWR"):
        bus.transfer(0x68, b"\x00\x10", 2)


def test_an_absent_address_on_an_smbus_only_adapter_is_a_nack_error() -> None:
    bus = LinuxI2CBus("/dev/i2c-0", smbus=FakeSMBusOnly(present=0x68))
    with pytest.raises(NackError, match="0x50"):
        bus.transfer(0x50, b"\x00", 1)


def test_the_run_summary_names_the_mode_an_smbus_only_adapter_is_read_in() -> None:
    registry = load_registry()
    profile = parse_profile(
        "schema_version: 1\nname: smbus-board\nbuses:\n  i2c: {kind: i2c, device: /dev/i2c-0}\n"
        "devices:\n  imu: {driver: mpu9250, bus: i2c, address: 0x68}\n",
        "smbus-board.yaml", registry)
    adapter = FakeSMBusOnly(present=0x68)
    adapter.memory[0x75] = 0x71  # WHO_AM_I of an MPU-9250
    board = HardwareBoard({"i2c": LinuxI2CBus("/dev/i2c-0", smbus=adapter)}, SimulatedClock())
    with Pipeline(profile, registry, board) as pipeline:
        described = pipeline.summary().describe()
    assert "bus i2c: i2c:///dev/i2c-0: SMBus transfers" in described


def test_forced_combined_transfers_on_an_smbus_only_adapter_fail_naming_the_mode() -> None:
    # what every transfer did before the bus read I2C_FUNCS (the kernel's EOPNOTSUPP)
    bus = LinuxI2CBus("/dev/i2c-0", smbus=FakeSMBusOnly(), mode="i2c_rdwr")
    assert "forced (the adapter lacks I2C_FUNC_I2C" in bus.describe()
    with pytest.raises(BusError, match=r"\(i2c_rdwr\): .*Operation not supported"):
        bus.transfer(0x68, b"\x75", 1)


def test_forced_smbus_transfers_on_a_full_adapter_go_through_smbus_calls() -> None:
    adapter = FakeSMBusOnly(funcs=int(I2cFunc.I2C) | I2C_STUB_FUNCS)
    bus = LinuxI2CBus("/dev/i2c-1", smbus=adapter, mode="smbus")
    assert bus.mode == "smbus"
    assert bus.transfer(0x68, b"\x10", 2) == bytes([0x10, 0x11])
    assert adapter.calls == [("read_i2c_block", 0x10, 2)]


@pytest.mark.parametrize("mode", ["auto", "i2c_rdwr", "smbus"])
def test_the_profile_takes_the_transfer_mode_and_refuses_others(mode: str) -> None:
    registry = load_registry()
    text = ("schema_version: 1\nname: forced\nbuses:\n  i2c: {kind: i2c, device: /dev/i2c-0, "
            "transfer_mode: MODE}\ndevices:\n  imu: {driver: mpu9250, bus: i2c, address: 0x68}\n")
    profile = parse_profile(text.replace("MODE", mode), "forced.yaml", registry)
    assert profile.buses["i2c"].transfer_mode == mode  # type: ignore[attr-defined]
    with pytest.raises(ProfileError, match="transfer_mode"):
        parse_profile(text.replace("MODE", "rdwr"), "forced.yaml", registry)
