"""SPI through the kernel's spidev: drivers probe, configure and read /dev/spidevB.0.

The chip is the project's imuhal_spi_regs controller (tests/kernel/modules): a register file
behind the usual SPI register protocol (first byte the address, bit 7 set to read, then
auto-increment), whose map the test loads from user space through its sysfs ``registers``
file, as the chip would show it. Expected values are the datasheets' (MPU-9250 register map
rev 1.4: 8192 LSB/g at +/-4 g; MAX21100: WHO_AM_I 0xB2, 7500 LSB/g at +/-4 g, data words
big-endian from 0x24, status 0x23 with GYRO_DR bit 0 and ACC_DR bit 2).
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import pytest
from tests.kernel.guest import loaded_module, wait_for

from imuhal.bus.linux_spi import LinuxSPIBus
from imuhal.core.clock import MonotonicClock
from imuhal.core.samples import AccelSample
from imuhal_chips.max2110x.driver import Max21100Driver
from imuhal_chips.mpu9250.driver import MPU9250Driver

G_M_S2 = 9.80665
PLATFORM = Path("/sys/devices/platform/imuhal-spi-regs")


@dataclass(frozen=True)
class RegisterChip:
    bus: int
    """B of /dev/spidevB.0"""
    registers: Path

    def load(self, values: dict[int, bytes]) -> None:
        image = bytearray(self.registers.read_bytes())
        for register, data in values.items():
            image[register:register + len(data)] = data
        self.registers.write_bytes(bytes(image))

    def peek(self, register: int, length: int = 1) -> bytes:
        return self.registers.read_bytes()[register:register + length]


def _chip(addr_mask: int) -> Iterator[RegisterChip]:
    with loaded_module("imuhal_spi_regs", f"addr_mask={addr_mask:#x}"):
        masters = list((PLATFORM / "spi_master").glob("spi*"))
        assert len(masters) == 1, masters
        bus = int(masters[0].name.removeprefix("spi"))
        wait_for(Path(f"/dev/spidev{bus}.0"))
        yield RegisterChip(bus, PLATFORM / "registers")


@pytest.fixture
def mpu_chip() -> Iterator[RegisterChip]:
    yield from _chip(0x7F)  # MPU-9250: seven address bits


@pytest.fixture
def max_chip() -> Iterator[RegisterChip]:
    yield from _chip(0x3F)  # MAX21100: six address bits, bit 6 stops auto-increment


def words_be(*counts: int) -> bytes:
    return b"".join(c.to_bytes(2, "big", signed=True) for c in counts)


def test_mpu9250_probes_configures_and_reads_through_spidev(mpu_chip: RegisterChip) -> None:
    mpu_chip.load({0x75: b"\x71", 0x3A: b"\x01", 0x3B: words_be(0, 4096, -8192, 0, 0, 0, 0)})
    clock = MonotonicClock()
    with LinuxSPIBus(mpu_chip.bus, mode=3) as bus:
        driver = MPU9250Driver(bus.link(0), {"odr_hz": 200, "accel_range_g": 4}, device="imu",
                               clock=clock)
        assert driver.probe().identity == "WHO_AM_I=0x71"
        driver.configure()
        # USER_CTRL: I2C_IF_DIS (SPI only) and I2C_MST_EN (the AK8963 through the master)
        assert mpu_chip.peek(0x6A) == b"\x30"
        assert mpu_chip.peek(0x19) == b"\x04" and mpu_chip.peek(0x1C) == b"\x08"
        driver.start(clock.now_ns())
        accel = next(s for s in driver.poll(clock.now_ns()).samples
                     if isinstance(s, AccelSample))
    assert accel.valid
    assert accel.accel_m_s2 == pytest.approx((0.0, 0.5 * G_M_S2, -G_M_S2), rel=1e-6)


def test_max21100_probes_configures_and_reads_through_spidev(max_chip: RegisterChip) -> None:
    max_chip.load({0x20: b"\xb2", 0x23: b"\x05", 0x24: words_be(0, 0, 0, 7500, 0, -3750)})
    clock = MonotonicClock()
    with LinuxSPIBus(max_chip.bus, mode=3) as bus:
        driver = Max21100Driver(bus.link(0), {"accel_range_g": 4}, device="imu", clock=clock)
        assert driver.probe().identity == "WHO_AM_I=0xB2"
        driver.configure()
        # PWR_ACC_CFG[7:6] = 0b10 selects +/-4 g
        assert max_chip.peek(0x04)[0] >> 6 == 0b10
        driver.start(clock.now_ns())
        accel = next(s for s in driver.poll(clock.now_ns()).samples
                     if isinstance(s, AccelSample))
    assert accel.valid
    assert accel.accel_m_s2 == pytest.approx((G_M_S2, 0.0, -0.5 * G_M_S2), rel=1e-6)
