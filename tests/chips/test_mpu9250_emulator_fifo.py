"""The MPU-9250 emulator's FIFO, driven by raw register writes. Register numbers and bits
are written here from the register map (RM-MPU-9250A-00 rev 1.4: CONFIG 0x1A [6]
FIFO_MODE, FIFO_EN 0x23 [7] TEMP [6:4] GYRO X/Y/Z [3] ACCEL [0] SLV0, INT_ENABLE 0x38 and
INT_STATUS 0x3A [4] FIFO_OFLOW, USER_CTRL 0x6A [6] FIFO_EN [2] FIFO_RST, FIFO_COUNTH/L
0x72/0x73, FIFO_R_W 0x74; 512 bytes), not imported from the driver."""

from __future__ import annotations

import struct

from imuhal.bus.base import BusKind
from imuhal.core.clock import SimulatedClock
from imuhal.emulation import EmulatedBus, PhysicalInputs
from imuhal_chips.ak8963.emulator import AK8963Emulator
from imuhal_chips.mpu9250.emulator import MPU9250Emulator

MPU = 0x68
SMPLRT_DIV, CONFIG, FIFO_EN, INT_ENABLE, INT_STATUS = 0x19, 0x1A, 0x23, 0x38, 0x3A
I2C_SLV0_ADDR, I2C_SLV0_REG, I2C_SLV0_CTRL = 0x25, 0x26, 0x27
USER_CTRL, PWR_MGMT_1, FIFO_COUNTH, FIFO_R_W = 0x6A, 0x6B, 0x72, 0x74
G = 9.80665


class Rig:
    def __init__(self, fifo_en: int, *, user: int = 0x40) -> None:
        self.clock = SimulatedClock()
        self.bus = EmulatedBus("host", BusKind.I2C)
        self.mpu = self.bus.attach(MPU, MPU9250Emulator(self.clock))
        self.write(PWR_MGMT_1, 0x01)
        self.write(CONFIG, 0x03)  # DLPF 41 Hz: 1 kHz internal
        self.write(SMPLRT_DIV, 4)  # 200 Hz
        self.write(FIFO_EN, fifo_en)
        self.write(USER_CTRL, user | 0x04)  # FIFO_EN (and its reset)

    def write(self, reg: int, value: int) -> None:
        self.bus.transfer(MPU, bytes([reg, value]), 0)

    def read(self, reg: int, n: int) -> bytes:
        return self.bus.transfer(MPU, bytes([reg]), n)

    def count(self) -> int:
        high, low = self.read(FIFO_COUNTH, 2)
        return (high & 0x1F) << 8 | low


def test_each_sample_appends_accel_temperature_gyro_in_register_order() -> None:
    rig = Rig(0x80 | 0x70 | 0x08)  # TEMP, GYRO X/Y/Z, ACCEL: 14 bytes a sample
    # +-2 g: 16384 LSB/g; +-250 dps: 131 LSB/(deg/s) (power-on ranges)
    rig.mpu.set_physics(PhysicalInputs(specific_force_m_s2=(G / 2, 0.0, G),
                                       angular_rate_rad_s=(0.0, 0.0, 0.0),
                                       temperature_degc=21.0))
    rig.clock.sleep(0.0201)  # samples at 5, 10, 15 and 20 ms
    assert rig.count() == 4 * 14
    frame = rig.read(FIFO_R_W, 14)
    assert struct.unpack(">7h", frame) == (8192, 0, 16384, 0, 0, 0, 0)
    assert rig.count() == 3 * 14  # the burst popped one frame


def test_a_burst_from_fifo_r_w_pops_instead_of_moving_on() -> None:
    rig = Rig(0x08)  # accel only: 6 bytes
    rig.clock.sleep(0.0101)
    both = rig.read(FIFO_R_W, 12)
    assert both[:6] == both[6:] and rig.count() == 0


def test_slave0s_bytes_follow_the_sensor_data() -> None:
    rig = Rig(0x08 | 0x01, user=0x40 | 0x20)  # ACCEL + SLV0, I2C master on
    ak = rig.mpu.child_buses()["aux"].attach(0x0C, AK8963Emulator(rig.clock))
    ak.bus_transfer(BusKind.I2C, bytes([0x0A, 0x16]), 0)  # 16-bit, 100 Hz
    rig.write(I2C_SLV0_ADDR, 0x80 | 0x0C)
    rig.write(I2C_SLV0_REG, 0x00)  # WIA, INFO, ST1, ...
    rig.write(I2C_SLV0_CTRL, 0x80 | 1)  # one byte: WIA 0x48
    rig.clock.sleep(0.0051)
    frame = rig.read(FIFO_R_W, rig.count())
    assert len(frame) == 7 and frame[6] == 0x48


def test_overflow_overwrites_the_oldest_bytes_and_sets_the_status() -> None:
    rig = Rig(0x08)
    rig.write(INT_ENABLE, 0x10)
    rig.clock.sleep(0.5)  # 100 samples of 6 bytes: 600 > 512
    assert rig.count() == 512
    assert rig.read(INT_STATUS, 1)[0] & 0x10


def test_fifo_mode_1_keeps_the_first_samples_and_drops_the_rest() -> None:
    rig = Rig(0x08)
    rig.write(CONFIG, 0x40 | 0x03)
    rig.mpu.set_physics(PhysicalInputs(specific_force_m_s2=(0.0, 0.0, G)))
    rig.clock.sleep(0.5)
    assert rig.count() == 85 * 6  # whole samples that fit in 512 bytes


def test_fifo_rst_empties_it_and_an_empty_fifo_counts_zero() -> None:
    rig = Rig(0x08)
    rig.clock.sleep(0.05)
    assert rig.count() > 0
    rig.write(USER_CTRL, 0x40 | 0x04)
    assert rig.count() == 0


def test_without_user_ctrl_fifo_en_nothing_is_stored() -> None:
    rig = Rig(0x08, user=0x00)
    rig.clock.sleep(0.05)
    assert rig.count() == 0
