"""I2C through the kernel's i2c-dev: the MPU-9250 and HMC5883L drivers on two real adapters.

* ``smbus-only``: the kernel's i2c-stub, SMBus transfers only (I2C_FUNCS without I2C_FUNC_I2C,
  like PC SMBus hosts): LinuxI2CBus must fall back to SMBus block transfers.
* ``full-i2c``: the project's imuhal_i2c_regs adapter (tests/kernel/modules), I2C messages so
  I2C_RDWR works.

Both hold the chips as register files: each test loads the registers a real chip would show
(identity, data-ready, data words) through the adapter with smbus2, then runs the driver. The
expected values come from the datasheets (MPU-9250 register map rev 1.4: 8192 LSB/g at
+/-4 g, 65.5 LSB/(deg/s) at +/-500 deg/s, T = counts/333.87 + 21 degC; HMC5883L rev E: 1090
LSB/gauss at +/-1.3 Ga, data order X, Z, Y big-endian).

The bus before it read I2C_FUNCS sent every transfer through I2C_RDWR; ``transfer_mode:
i2c_rdwr`` still does, which shows on the SMBus-only adapter what that code did there.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from dataclasses import dataclass

import pytest
from smbus2 import SMBus
from tests.kernel.guest import i2c_device_named, loaded_module

from imuhal.bus.linux_i2c import LinuxI2CBus
from imuhal.core.clock import MonotonicClock
from imuhal.core.errors import BusError, NackError
from imuhal.core.samples import AccelSample, GyroSample, MagSample, TemperatureSample
from imuhal_chips.hmc5883l.driver import Hmc5883lDriver
from imuhal_chips.mpu9250.driver import MPU9250Driver

G_M_S2 = 9.80665
MPU, HMC, ABSENT = 0x68, 0x1E, 0x50


@dataclass(frozen=True)
class Adapter:
    device: str
    mode: str


@pytest.fixture(params=["smbus-only", "full-i2c"])
def adapter(request: pytest.FixtureRequest) -> Iterator[Adapter]:
    addresses = f"{MPU:#x},{HMC:#x}"
    if request.param == "smbus-only":
        with loaded_module("i2c-stub", f"chip_addr={addresses}"):
            yield Adapter(i2c_device_named("SMBus stub driver"), "smbus")
    else:
        with loaded_module("imuhal_i2c_regs", f"addrs={addresses}"):
            yield Adapter(i2c_device_named("imuhal register-file adapter"), "i2c_rdwr")


def load(device: str, address: int, registers: dict[int, bytes]) -> None:
    """Write register contents as the chip would show them, through the adapter."""
    with SMBus(device) as smbus:
        for register, data in registers.items():
            smbus.write_i2c_block_data(address, register, list(data))


def peek(device: str, address: int, register: int, length: int = 1) -> bytes:
    with SMBus(device) as smbus:
        return bytes(smbus.read_i2c_block_data(address, register, length))


def words_be(*counts: int) -> bytes:
    return b"".join(c.to_bytes(2, "big", signed=True) for c in counts)


def test_the_bus_picks_its_transfer_mode_from_the_adapters_i2c_funcs(adapter: Adapter) -> None:
    with LinuxI2CBus(adapter.device) as bus:
        assert bus.mode == adapter.mode
        assert ("SMBus transfers" in bus.describe()) == (adapter.mode == "smbus")


def test_mpu9250_probes_configures_and_reads_through_i2c_dev(adapter: Adapter) -> None:
    accel_counts, gyro_counts, temp_counts = (4096, -2048, 8192), (655, -1310, 1965), 1335
    load(adapter.device, MPU, {0x75: b"\x71", 0x3A: b"\x01",
                               0x3B: words_be(*accel_counts, temp_counts, *gyro_counts)})
    clock = MonotonicClock()
    with LinuxI2CBus(adapter.device) as bus:
        driver = MPU9250Driver(bus.link(MPU), {"odr_hz": 200, "accel_range_g": 4,
                                               "gyro_range_dps": 500}, device="imu",
                               clock=clock)
        assert driver.probe().identity == "WHO_AM_I=0x71"
        driver.configure()
        # the configuration reached the chip's registers: SMPLRT_DIV 4 (1 kHz / 5 = 200 Hz),
        # GYRO_CONFIG FS_SEL 1, ACCEL_CONFIG AFS_SEL 1, INT_PIN_CFG bypass, INT_ENABLE RAW_RDY
        assert peek(adapter.device, MPU, 0x19) == b"\x04"
        assert peek(adapter.device, MPU, 0x1B, 2) == b"\x08\x08"
        assert peek(adapter.device, MPU, 0x37, 2) == b"\x02\x01"
        driver.start(clock.now_ns())
        samples = driver.poll(clock.now_ns()).samples
        accel = next(s for s in samples if isinstance(s, AccelSample))
        gyro = next(s for s in samples if isinstance(s, GyroSample))
        temp = next(s for s in samples if isinstance(s, TemperatureSample))
        assert accel.valid and gyro.valid and temp.valid
        assert accel.accel_m_s2 == pytest.approx((0.5 * G_M_S2, -0.25 * G_M_S2, G_M_S2),
                                                 rel=1e-6)
        assert gyro.gyro_rad_s == pytest.approx(
            tuple(math.radians(c / 65.5) for c in gyro_counts), rel=1e-6)
        assert temp.temperature_degc == pytest.approx(temp_counts / 333.87 + 21.0, abs=1e-6)
        # a new measurement in the chip's registers is what the next poll reads
        load(adapter.device, MPU, {0x3B: words_be(-8192, 0, 0)})
        accel = next(s for s in driver.poll(clock.now_ns()).samples
                     if isinstance(s, AccelSample))
        assert accel.accel_m_s2 == pytest.approx((-G_M_S2, 0.0, 0.0), abs=1e-9)


def test_hmc5883l_probes_configures_and_reads_through_i2c_dev(adapter: Adapter) -> None:
    x, y, z = 545, 109, -218  # 0.5, 0.1, -0.2 gauss at 1090 LSB/gauss
    load(adapter.device, HMC, {0x03: words_be(x, z, y), 0x09: b"\x01", 0x0A: b"H43"})
    clock = MonotonicClock()
    with LinuxI2CBus(adapter.device) as bus:
        driver = Hmc5883lDriver(bus.link(HMC), {"range_gauss": 1.3, "odr_hz": 75,
                                                "averaging": 8}, device="mag", clock=clock)
        assert driver.probe().identity == "ID=H43"
        driver.configure()
        # Config A: 8-sample average, 75 Hz; Config B: gain 1 (+/-1.3 Ga); Mode: continuous
        assert peek(adapter.device, HMC, 0x00, 3) == b"\x78\x20\x00"
        driver.start(clock.now_ns())
        samples: list[MagSample] = []
        for _ in range(3):  # the first measurement after a gain change is dropped
            samples += [s for s in driver.poll(clock.now_ns()).samples
                        if isinstance(s, MagSample)]
        assert samples and samples[0].valid
        assert samples[0].mag_ut == pytest.approx((50.0, 10.0, -20.0), rel=1e-6)


def test_an_absent_address_is_a_nack_error_naming_it(adapter: Adapter) -> None:
    with LinuxI2CBus(adapter.device) as bus, pytest.raises(NackError, match="0x50"):
        bus.transfer(ABSENT, b"\x75", 1)


def test_the_pre_fix_i2c_rdwr_transfers_fail_on_the_smbus_only_adapter_where_auto_reads(
        ) -> None:
    with loaded_module("i2c-stub", f"chip_addr={MPU:#x}"):
        device = i2c_device_named("SMBus stub driver")
        load(device, MPU, {0x75: b"\x71"})
        clock = MonotonicClock()
        with LinuxI2CBus(device, mode="i2c_rdwr") as bus:
            driver = MPU9250Driver(bus.link(MPU), {}, device="imu", clock=clock)
            with pytest.raises(BusError, match=r"\(i2c_rdwr\): .*Operation not supported"):
                driver.probe()
        with LinuxI2CBus(device) as bus:
            assert bus.mode == "smbus"
            driver = MPU9250Driver(bus.link(MPU), {}, device="imu", clock=clock)
            assert driver.probe().identity == "WHO_AM_I=0x71"
