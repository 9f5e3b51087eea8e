"""The MPU-9250 emulator's slave 0 reading the AK8963 emulator into EXT_SENS_DATA, driven by
raw register writes. Register numbers and bits are written here from the register map
(RM-MPU-9250A-00 rev 1.4: I2C_SLV0_ADDR/REG/CTRL 0x25..0x27 with RNW, EN, BYTE_SW, REG_DIS,
GRP, LENG; I2C_SLV4_CTRL 0x34 [4:0] I2C_MST_DLY; I2C_MST_STATUS 0x36 [0] I2C_SLV0_NACK;
EXT_SENS_DATA_00 0x49; I2C_MST_DELAY_CTRL 0x67 [0] I2C_SLV0_DLY_EN; USER_CTRL 0x6A [5]
I2C_MST_EN) and the AK8963's section 5 (ST1 0x02 DRDY, HXL..HZH little-endian, ST2 0x09,
CNTL1 0x0A), not imported from the driver."""

from __future__ import annotations

import struct

from imuhal.bus.base import BusKind
from imuhal.core.clock import SimulatedClock
from imuhal.emulation import EmulatedBus, PhysicalInputs
from imuhal_chips.ak8963.emulator import DEFAULT_ASA, AK8963Emulator
from imuhal_chips.mpu9250.emulator import MPU9250Emulator

MPU = 0x68
SMPLRT_DIV, CONFIG, I2C_SLV0_ADDR, I2C_SLV0_REG, I2C_SLV0_CTRL = 0x19, 0x1A, 0x25, 0x26, 0x27
I2C_SLV4_CTRL, I2C_MST_STATUS, EXT_SENS_DATA_00 = 0x34, 0x36, 0x49
I2C_MST_DELAY_CTRL, USER_CTRL, PWR_MGMT_1 = 0x67, 0x6A, 0x6B
EN, BYTE_SW, GRP, RNW = 0x80, 0x40, 0x10, 0x80
COUNTS = (1234, -2345, 3456)


class Rig:
    def __init__(self) -> None:
        self.clock = SimulatedClock()
        self.bus = EmulatedBus("host", BusKind.I2C)
        self.mpu = self.bus.attach(MPU, MPU9250Emulator(self.clock))
        self.ak = self.mpu.child_buses()["aux"].attach(0x0C, AK8963Emulator(self.clock))
        # counts = field / (0.15 uT * adjustment): chosen field gives these counts exactly
        adjust = [(a - 128) * 0.5 / 128 + 1 for a in DEFAULT_ASA]
        self.ak.set_physics(PhysicalInputs(magnetic_field_ut=tuple(
            c * 0.15 * f for c, f in zip(COUNTS, adjust, strict=True))))
        self.write(PWR_MGMT_1, 0x01)
        self.write(CONFIG, 0x03)  # 1 kHz internal
        self.write(SMPLRT_DIV, 4)  # 200 Hz
        self.write(USER_CTRL, 0x20)  # I2C_MST_EN
        self.ak.bus_transfer(BusKind.I2C, bytes([0x0A, 0x16]), 0)  # 16-bit, 100 Hz

    def write(self, reg: int, value: int) -> None:
        self.bus.transfer(MPU, bytes([reg, value]), 0)

    def read(self, reg: int, n: int) -> bytes:
        return self.bus.transfer(MPU, bytes([reg]), n)

    def slave0(self, register: int, ctrl: int) -> None:
        self.write(I2C_SLV0_ADDR, RNW | 0x0C)
        self.write(I2C_SLV0_REG, register)
        self.write(I2C_SLV0_CTRL, ctrl)


def test_slave0_copies_st1_to_st2_as_the_ak8963_sends_them() -> None:
    rig = Rig()
    rig.slave0(0x02, EN | 8)
    rig.clock.sleep(0.0201)
    rig.read(0x3A, 1)
    data = rig.read(EXT_SENS_DATA_00, 8)
    assert data[0] & 0x01  # DRDY of a measurement the master had not read yet
    assert struct.unpack("<3h", data[1:7]) == COUNTS
    assert data[7] & 0x10  # ST2.BITM: 16-bit


def test_reading_st2_in_the_group_releases_the_data_so_the_next_copy_has_drdy_clear() -> None:
    rig = Rig()
    rig.write(SMPLRT_DIV, 0)  # 1 kHz samples
    rig.clock.sleep(0.0101)  # one measurement done (100 Hz)
    rig.slave0(0x02, EN | 8)
    rig.clock.sleep(0.0010)  # the next sample reads it ...
    first = rig.read(EXT_SENS_DATA_00, 1)[0]
    rig.clock.sleep(0.0010)  # ... the one after, before the next measurement, finds no new
    second = rig.read(EXT_SENS_DATA_00, 1)[0]
    assert first & 0x01 and not second & 0x01


def test_byte_sw_with_grp_swaps_the_words_that_end_on_an_even_register() -> None:
    """From ST1 (0x02) with GRP = 1 the pairs are (0x03, 0x04), (0x05, 0x06), (0x07, 0x08):
    the data words become big-endian, ST1 and ST2 stay in place."""
    rig = Rig()
    rig.slave0(0x02, EN | BYTE_SW | GRP | 8)
    rig.clock.sleep(0.0201)
    data = rig.read(EXT_SENS_DATA_00, 8)
    assert struct.unpack(">3h", data[1:7]) == COUNTS and data[7] & 0x10


def test_byte_sw_without_grp_swaps_pairs_ending_on_an_odd_register() -> None:
    """The Linux recipe's start, HXL (0x03), with GRP = 0: pairs (0x02, 0x03) would be
    grouped, so 0x03 ends a pair alone; then (0x04, 0x05), (0x06, 0x07), (0x08, 0x09)."""
    rig = Rig()
    rig.slave0(0x03, EN | BYTE_SW | 7)
    rig.clock.sleep(0.0201)
    data = rig.read(EXT_SENS_DATA_00, 7)
    plain = bytearray(struct.pack("<3h", *COUNTS))
    assert data[0] == plain[0] and data[1:3] == bytes([plain[2], plain[1]])


def test_slave0_dly_en_reads_only_every_one_plus_i2c_mst_dly_samples() -> None:
    reads = []
    for delay_ctrl in (0x00, 0x01):
        rig = Rig()
        rig.write(I2C_SLV4_CTRL, 3)  # I2C_MST_DLY 3, EN clear
        rig.write(I2C_MST_DELAY_CTRL, delay_ctrl)
        rig.slave0(0x02, EN | 8)
        before = rig.mpu.aux_bus.transfers
        for _ in range(40):  # 40 samples at 200 Hz
            rig.clock.sleep(0.005)
            rig.read(0x3A, 1)
        reads.append(rig.mpu.aux_bus.transfers - before)
    assert reads == [40, 10]


def test_a_nack_sets_slv0_nack_and_keeps_ext_sens_data() -> None:
    rig = Rig()
    rig.slave0(0x02, EN | 8)
    rig.clock.sleep(0.0201)
    kept = rig.read(EXT_SENS_DATA_00, 8)
    rig.read(I2C_MST_STATUS, 1)  # clear
    rig.ak.absent = True
    rig.clock.sleep(0.0201)
    assert rig.read(I2C_MST_STATUS, 1)[0] & 0x01
    assert rig.read(EXT_SENS_DATA_00, 8) == kept
    assert not rig.read(I2C_MST_STATUS, 1)[0] & 0x01  # cleared by the read
