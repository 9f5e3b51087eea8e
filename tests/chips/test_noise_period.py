"""Each emulator reports the output period its registers configure
(``ChipEmulator.noise_period_s``), which the simulator's noise band follows; None where the
chip outputs at no rate of its own."""

from __future__ import annotations

import pytest

from imuhal.bus.base import BusKind
from imuhal.core.quantities import Quantity
from imuhal_chips.ak8963 import registers as ak
from imuhal_chips.ak8963.emulator import AK8963Emulator
from imuhal_chips.mpu9250 import registers as mpu
from imuhal_chips.mpu9250.emulator import MPU9250Emulator


def _write(emulator, reg: int, value: int) -> None:  # type: ignore[no-untyped-def]
    emulator.bus_transfer(BusKind.I2C, bytes([reg, value]), 0)


def test_mpu9250_period_is_the_sample_rate_of_its_divider() -> None:
    imu = MPU9250Emulator()
    _write(imu, mpu.PWR_MGMT_1, 0x00)
    _write(imu, mpu.CONFIG, 3)        # DLPF 41 Hz: 1 kHz internal rate
    _write(imu, mpu.SMPLRT_DIV, 4)    # / (1 + 4): 200 Hz
    assert imu.noise_period_s(Quantity.GYRO) == pytest.approx(0.005)
    assert imu.noise_period_s(Quantity.ACCEL) == pytest.approx(0.005)
    assert imu.noise_period_s(Quantity.MAG) is None  # the AK8963 is its own chip
    _write(imu, mpu.PWR_MGMT_1, mpu.PWR1_SLEEP)
    assert imu.noise_period_s(Quantity.GYRO) is None  # asleep: no output rate


@pytest.mark.parametrize(("mode", "period_s"), [(0x12, 1 / 8), (0x16, 1 / 100), (0x11, None)])
def test_ak8963_period_follows_the_continuous_mode(mode: int, period_s: float | None) -> None:
    mag = AK8963Emulator()
    _write(mag, ak.REG_CNTL1, mode)
    assert mag.noise_period_s(Quantity.MAG) == period_s  # single (0x11): the host's pace
    assert mag.min_output_period_s == pytest.approx(7.2e-3)


def test_mpu9250_noise_bandwidth_is_its_low_pass_filter_setting() -> None:
    imu = MPU9250Emulator()
    _write(imu, mpu.PWR_MGMT_1, 0x00)
    _write(imu, mpu.CONFIG, 3)            # DLPF_CFG 3: gyro 41 Hz
    _write(imu, mpu.ACCEL_CONFIG2, 3)     # A_DLPF_CFG 3: accel 44.8 Hz
    assert imu.noise_bandwidth_hz(Quantity.GYRO) == 41.0
    assert imu.noise_bandwidth_hz(Quantity.ACCEL) == 44.8
    _write(imu, mpu.GYRO_CONFIG, 0b01)    # Fchoice_b x1: filter bypassed, 8800 Hz
    _write(imu, mpu.ACCEL_CONFIG2, 0b1000)  # accel_fchoice_b: 1130 Hz
    assert imu.noise_bandwidth_hz(Quantity.GYRO) == 8800.0
    assert imu.noise_bandwidth_hz(Quantity.ACCEL) == 1130.0
    assert imu.noise_bandwidth_hz(Quantity.MAG) is None


def test_max21100_noise_bandwidth_is_its_filter_setting() -> None:
    from imuhal_chips.max2110x.emulator import Max21100Emulator
    from imuhal_chips.max2110x.registers import Reg

    imu = Max21100Emulator()
    assert imu.noise_bandwidth_hz(Quantity.GYRO) is None  # powered down at reset
    _write(imu, Reg.POWER_CFG, 0b1111 << 3)                # gyro and accel on
    _write(imu, Reg.GYRO_CFG1, 5 << 2)                     # bandwidth code 5: 14 Hz
    _write(imu, Reg.ACC_CFG1, 0b00 << 4 | 0x06)            # divisor 48 of the accel ODR
    assert imu.noise_bandwidth_hz(Quantity.GYRO) == 14.0
    odr_hz = 1.0 / imu.noise_period_s(Quantity.ACCEL)
    assert imu.noise_bandwidth_hz(Quantity.ACCEL) == pytest.approx(odr_hz / 48)
