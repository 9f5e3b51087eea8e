"""Every bundled driver's stream specs (imuhal.core.streams): after configure() they follow
the configured range and rate, and they are read from the chip: a configuration register
changed on the chip's side shows in the spec once the driver reads it again
(``refresh_streams``), which a driver copying its settings would miss.

The chip-side change goes through a second link on the emulated bus, as another master or a
glitch would write it; the emulators decode their registers from the datasheet side."""

from __future__ import annotations

import math
from pathlib import Path

import pytest
from tests.support.fake_iio import Element, FakeIIODevice

from imuhal.bus.base import BusKind
from imuhal.bus.linux_iio import LinuxIIOBus
from imuhal.bus.registers import RegisterView
from imuhal.core.clock import SimulatedClock
from imuhal.core.quantities import Quantity
from imuhal.core.samples import Frame
from imuhal.core.streams import StreamSpec, TimeSource
from imuhal.drivers.base import Driver
from imuhal.emulation import EmulatedBus
from imuhal_chips.ak8963 import registers as ak
from imuhal_chips.ak8963.driver import AK8963Driver
from imuhal_chips.ak8963.emulator import AK8963Emulator
from imuhal_chips.bmp280 import registers as bmp
from imuhal_chips.bmp280.driver import BMP280Driver
from imuhal_chips.bmp280.emulator import BMP280Emulator
from imuhal_chips.hmc5883l.driver import Hmc5883lDriver
from imuhal_chips.hmc5883l.emulator import Hmc5883lEmulator
from imuhal_chips.iio.driver import IIODriver
from imuhal_chips.max2110x.driver import Max21100Driver
from imuhal_chips.max2110x.emulator import Max21100Emulator
from imuhal_chips.max2110x.registers import Reg, convention_for
from imuhal_chips.mpu9250 import registers as mpu
from imuhal_chips.mpu9250.driver import MPU9250Driver
from imuhal_chips.mpu9250.emulator import MPU9250Emulator
from imuhal_chips.ms5611.driver import MS5611Driver
from imuhal_chips.ms5611.emulator import MS5611Emulator

G = 9.80665


def configured(driver: Driver) -> Driver:
    driver.probe()
    driver.configure()
    return driver


def spec(driver: Driver, quantity: Quantity) -> StreamSpec:
    found = driver.stream(quantity)
    assert found is not None, f"{driver.name} declares no {quantity} stream"
    return found


def test_a_driver_declares_no_stream_before_configure() -> None:
    clock = SimulatedClock()
    bus = EmulatedBus("spi0", BusKind.SPI)
    bus.attach(0, Max21100Emulator(clock))
    driver = Max21100Driver(bus.link(0), {}, device="imu", clock=clock)
    assert driver.streams() == () and driver.full_scale(Quantity.GYRO) is None


# --- MAX21100 -------------------------------------------------------------------------------

def _max21100(**settings: object) -> tuple[Max21100Driver, RegisterView]:
    clock = SimulatedClock()
    bus = EmulatedBus("spi0", BusKind.SPI)
    bus.attach(0, Max21100Emulator(clock))
    driver = Max21100Driver(bus.link(0), settings, device="imu", clock=clock)
    return configured(driver), RegisterView(bus.link(0), convention_for(BusKind.SPI))


@pytest.mark.parametrize(("range_dps", "odr_hz"), [(500, 250), (1000, 500), (2000, 1000)])
def test_max21100_gyro_spec_follows_the_configured_range_and_rate(range_dps: int,
                                                                  odr_hz: float) -> None:
    driver, _ = _max21100(gyro_range_dps=range_dps, gyro_odr_hz=odr_hz)
    gyro = spec(driver, Quantity.GYRO)
    assert gyro.full_scale == math.radians(range_dps)
    assert gyro.scale == pytest.approx(math.radians(range_dps) / 30000)  # 30000 counts
    assert (gyro.rate_hz, gyro.frame, gyro.unit) == (odr_hz, Frame.SENSOR, "rad/s")
    assert gyro.time_source is TimeSource.HOST_POLL
    assert driver.full_scale(Quantity.GYRO) == gyro.full_scale  # one source of truth


def test_max21100_accel_spec_follows_the_configured_range_and_rate() -> None:
    driver, _ = _max21100(accel_range_g=8, accel_odr_hz=125)
    accel = spec(driver, Quantity.ACCEL)
    assert accel.full_scale == 8 * G and accel.rate_hz == 125
    assert accel.scale == pytest.approx(8 * G / 30000)


def test_max21100_spec_follows_a_range_changed_in_the_chip() -> None:
    driver, side = _max21100(gyro_range_dps=500)
    cfg1 = side.read_u8(Reg.GYRO_CFG1)
    side.write(Reg.GYRO_CFG1, cfg1 & ~0x03)  # GYRO_CFG1[1:0] = 00: +-2000 dps
    assert spec(driver, Quantity.GYRO).full_scale == math.radians(500)  # not read yet
    driver.refresh_streams()
    assert spec(driver, Quantity.GYRO).full_scale == math.radians(2000)


def test_max21100_spec_follows_a_rate_changed_in_the_chip() -> None:
    driver, side = _max21100(gyro_odr_hz=250)
    side.write(Reg.GYRO_CFG2, 0x03)  # ODR code 3: 1 kHz
    assert spec(driver, Quantity.GYRO).rate_hz == 250
    assert {s.quantity: s.rate_hz for s in driver.refresh_streams()}[Quantity.GYRO] == 1000


# --- HMC5883L -------------------------------------------------------------------------------

def _hmc5883l(**settings: object) -> tuple[Hmc5883lDriver, EmulatedBus]:
    clock = SimulatedClock()
    bus = EmulatedBus("i2c1", BusKind.I2C)
    bus.attach(0x1E, Hmc5883lEmulator(clock))
    return configured(Hmc5883lDriver(bus.link(0x1E), settings, device="mag", clock=clock)), bus


def test_hmc5883l_spec_follows_the_configured_range_and_rate() -> None:
    driver, _ = _hmc5883l(range_gauss=4.0, odr_hz=30)
    mag = spec(driver, Quantity.MAG)
    # gain 440 LSB/Ga; the largest word before the -4096 overflow value is -2048 counts
    assert mag.scale == pytest.approx(100 / 440)
    assert mag.full_scale == pytest.approx(2048 * 100 / 440)
    assert (mag.rate_hz, mag.unit) == (30, "uT")


def test_hmc5883l_spec_follows_a_gain_changed_in_the_chip() -> None:
    driver, bus = _hmc5883l(range_gauss=1.3)
    bus.link(0x1E).transfer(bytes([0x01, 7 << 5]), 0)  # Config B: GN = 7, 230 LSB/Ga
    assert spec(driver, Quantity.MAG).full_scale == pytest.approx(2048 * 100 / 1090)
    driver.refresh_streams()
    assert spec(driver, Quantity.MAG).full_scale == pytest.approx(2048 * 100 / 230)


# --- AK8963 ---------------------------------------------------------------------------------

def _ak8963(**settings: object) -> tuple[AK8963Driver, RegisterView]:
    clock = SimulatedClock()
    bus = EmulatedBus("i2c1", BusKind.I2C)
    bus.attach(ak.I2C_ADDRESS, AK8963Emulator(clock))
    driver = AK8963Driver(bus.link(ak.I2C_ADDRESS), settings, device="mag", clock=clock)  # type: ignore[arg-type]
    return configured(driver), RegisterView(bus.link(ak.I2C_ADDRESS))  # type: ignore[return-value]


@pytest.mark.parametrize(("odr_hz", "bits", "ut_per_lsb"), [(8, 14, 0.6), (100, 16, 0.15)])
def test_ak8963_spec_follows_the_configured_mode_and_resolution(
        odr_hz: int, bits: int, ut_per_lsb: float) -> None:
    driver, _ = _ak8963(odr_hz=odr_hz, resolution_bits=bits)
    mag = spec(driver, Quantity.MAG)
    assert (mag.rate_hz, mag.scale, mag.full_scale) == (odr_hz, ut_per_lsb, 4912.0)


def test_ak8963_spec_follows_a_mode_changed_in_the_chip() -> None:
    driver, side = _ak8963(odr_hz=8, resolution_bits=14)
    side.write(ak.REG_CNTL1, ak.MODE_POWER_DOWN)  # modes change through power-down
    side.write(ak.REG_CNTL1, ak.CNTL1_BIT | ak.MODE_CONTINUOUS_2)
    driver.refresh_streams()
    mag = spec(driver, Quantity.MAG)
    assert (mag.rate_hz, mag.scale) == (100, 0.15)


# --- MPU-9250 -------------------------------------------------------------------------------

def _mpu9250(**settings: object) -> tuple[MPU9250Driver, RegisterView]:
    clock = SimulatedClock()
    bus = EmulatedBus("host", BusKind.I2C)
    emu = bus.attach(0x68, MPU9250Emulator(clock))
    emu.connect_bypass(bus)
    driver = MPU9250Driver(bus.link(0x68), settings, device="imu", clock=clock)  # type: ignore[arg-type]
    return configured(driver), RegisterView(bus.link(0x68))  # type: ignore[return-value]


def test_mpu9250_specs_follow_the_configured_ranges_and_rate() -> None:
    driver, _ = _mpu9250(gyro_range_dps=500, accel_range_g=8, odr_hz=250)
    gyro, accel = spec(driver, Quantity.GYRO), spec(driver, Quantity.ACCEL)
    assert gyro.full_scale == pytest.approx(math.radians(32768 / 65.5))
    assert accel.full_scale == pytest.approx(32768 / 4096 * G)
    assert gyro.rate_hz == accel.rate_hz == 250


def test_mpu9250_spec_follows_range_and_divider_changed_in_the_chip() -> None:
    driver, side = _mpu9250(gyro_range_dps=500)
    rate = spec(driver, Quantity.GYRO).rate_hz
    side.write(mpu.GYRO_CONFIG, 3 << 3)  # GYRO_FS_SEL = 3: +-2000 dps
    side.write(mpu.SMPLRT_DIV, side.read_u8(mpu.SMPLRT_DIV) * 2 + 1)  # half the rate
    driver.refresh_streams()
    gyro = spec(driver, Quantity.GYRO)
    assert gyro.full_scale == pytest.approx(math.radians(32768 / 16.4))
    assert gyro.rate_hz == pytest.approx(rate / 2)


# --- BMP280 ---------------------------------------------------------------------------------

def _bmp280(**settings: object) -> tuple[BMP280Driver, RegisterView]:
    clock = SimulatedClock()
    bus = EmulatedBus("i2c1", BusKind.I2C)
    bus.attach(0x76, BMP280Emulator(clock))
    driver = BMP280Driver(bus.link(0x76), settings, device="baro", clock=clock)  # type: ignore[arg-type]
    return configured(driver), RegisterView(bus.link(0x76))  # type: ignore[return-value]


def test_bmp280_spec_is_the_normal_mode_cycle_of_the_registers() -> None:
    driver, _ = _bmp280(mode="normal", pressure_oversampling=4, temperature_oversampling=1,
                        standby_ms=62.5)
    # typical measurement 1 + 2*1 + 2*4 + 0.5 = 11.5 ms, plus 62.5 ms standby
    assert spec(driver, Quantity.PRESSURE).rate_hz == pytest.approx(1000 / 74.0)


def test_bmp280_spec_follows_a_standby_changed_in_the_chip() -> None:
    driver, side = _bmp280(mode="normal", pressure_oversampling=4, temperature_oversampling=1,
                           standby_ms=62.5)
    ctrl, config = side.read_u8(bmp.REG_CTRL_MEAS), side.read_u8(bmp.REG_CONFIG)
    # the chip takes config writes only out of normal mode
    side.write(bmp.REG_CTRL_MEAS, ctrl & ~bmp.MODE_MASK)
    side.write(bmp.REG_CONFIG, (config & 0x1F) | (bmp.STANDBY_CODES_MS[125.0] << 5))
    side.write(bmp.REG_CTRL_MEAS, ctrl)
    driver.refresh_streams()
    assert spec(driver, Quantity.PRESSURE).rate_hz == pytest.approx(1000 / 136.5)


# --- MS5611, GNSS, IIO ------------------------------------------------------------------------

def test_ms5611_spec_is_the_drivers_conversion_grid() -> None:
    clock = SimulatedClock()
    bus = EmulatedBus("i2c1", BusKind.I2C)
    bus.attach(0x77, MS5611Emulator(clock))
    driver = configured(MS5611Driver(bus.link(0x77), {"odr_hz": 40, "temperature_every": 4},  # type: ignore[arg-type]
                                     device="baro", clock=clock))
    pressure, temperature = spec(driver, Quantity.PRESSURE), spec(driver, Quantity.TEMPERATURE)
    assert (pressure.rate_hz, temperature.rate_hz) == (40, 10)
    assert pressure.full_scale is None  # compensation bounds the output, no range flag


def test_gnss_spec_is_the_acknowledged_navigation_rate_on_receiver_epochs() -> None:
    pytest.importorskip("pyubx2", reason="the gps extra (pynmea2, pyubx2) is not installed")
    from imuhal_chips.gnss.driver import GnssDriver, GnssSettings
    from imuhal_chips.gnss.emulator import GnssEmulator

    clock = SimulatedClock()
    bus = EmulatedBus("emul://uart", BusKind.SERIAL)
    emulator = bus.attach(0, GnssEmulator(clock=clock))
    driver = GnssDriver(bus.link(0), GnssSettings(protocol="ubx", rate_hz=5), device="gps",
                        clock=clock)
    assert driver.streams() == ()
    configured(driver)
    velocity = spec(driver, Quantity.VELOCITY)
    assert emulator.rate_hz == velocity.rate_hz == 5
    assert velocity.time_source is TimeSource.RECEIVER_EPOCH
    assert velocity.scale is None and velocity.full_scale is None and velocity.frame is None


def test_iio_spec_is_the_sampling_frequency_the_kernel_reads_back(tmp_path: Path) -> None:
    attributes = {"in_anglvel_scale": "0.000266316", "sampling_frequency": "200",
                  "in_anglvel_x_raw": "0", "in_anglvel_y_raw": "0", "in_anglvel_z_raw": "0"}
    elements = [Element(f"in_anglvel_{a}", i, "be:s16/16>>0", ">h")
                for i, a in enumerate("xyz")]
    elements.append(Element("in_timestamp", 3, "le:s64/64>>0", "<q"))
    device = FakeIIODevice(tmp_path / "sys", tmp_path / "dev", 0, "mpu9250", attributes,
                           elements)
    driver = IIODriver(LinuxIIOBus(tmp_path / "sys", tmp_path / "dev").link(0),
                       {"name": "mpu9250"}, device="imu", clock=SimulatedClock())  # type: ignore[arg-type]
    configured(driver)
    gyro = spec(driver, Quantity.GYRO)
    assert (gyro.rate_hz, gyro.scale) == (200, 0.000266316)
    assert gyro.time_source is TimeSource.KERNEL_BUFFER
    (device.folder / "sampling_frequency").write_text("100\n")  # the kernel's choice
    driver.refresh_streams()
    assert spec(driver, Quantity.GYRO).rate_hz == 100
