"""MAX21100 / MAX21105 register map and setting tables (one family, two parts).

Sources (see imuhal's chip-facts notes, chips.md sections 5 and 6):
- MAX21105: Maxim MAX21105 User Guide rev 1.4 (Jul 2015) and datasheet; har-in-air max21105.c.
- MAX21100: no Maxim datasheet was found; addresses and fields agree across Kris Winer's
  sketch, AutoQuad max21100.c, har-in-air max21100.c and Hypereal max21100.c. Facts tagged
  [SS] there (one-shot master trigger, mag status bits) are marked so below.

Every table maps a physical setting to its register code and, where the setting sets the
scale, to the sensitivity. Full scale maps to +/-30000 counts (not +/-32768) on both parts.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from enum import IntEnum

from imuhal.bus.base import BusKind
from imuhal.bus.registers import RegisterConvention

STANDARD_GRAVITY_M_S2 = 9.80665
"""1 g in m/s^2, the unit the accelerometer sensitivity is specified in."""

FULL_SCALE_COUNTS = 30000
"""Counts at the configured full scale (60 LSB/dps at 500 dps, 7500 LSB/g at 4 g)."""

TEMP_LSB_PER_DEGC = 256.0
"""16-bit temperature: T[degC] = raw / 256 (6400 counts at 25 degC)."""

I2C_ADDRESSES = (0x58, 0x59)
"""7-bit I2C addresses: SA0 low, SA0 high."""


class Reg(IntEnum):
    """Register addresses. 0x00..0x1F are banked (bank 0 shown); 0x20..0x3F are common."""

    # bank 0 (same addresses on both parts; names follow the MAX21100 where they differ)
    POWER_CFG = 0x00  # MAX21105: SET_PWR
    GYRO_CFG1 = 0x01  # MAX21105: SNS_CFG_1
    GYRO_CFG2 = 0x02  # MAX21105: SNS_CFG_2
    GYRO_CFG3 = 0x03
    PWR_ACC_CFG = 0x04  # MAX21105: SET_ACC_PWR
    ACC_CFG1 = 0x05
    ACC_CFG2 = 0x06
    MAG_SLV_CFG = 0x07  # MAX21100 only
    MAG_SLV_ADD = 0x08  # MAX21100 only: 7-bit address of the aux slave
    MAG_SLV_REG = 0x09  # MAX21100 only
    MAG_MAP_REG = 0x0A  # MAX21100 only
    I2C_MST_ADD = 0x0B  # MAX21100 only: register of a one-shot master transaction
    I2C_MST_DATA = 0x0C  # MAX21100 only: data of a one-shot master transaction
    DR_CFG = 0x13  # MAX21105: SET_TEMP_DR
    I2C_CFG = 0x16  # MAX21105: MIF_CFG
    FIFO_TH = 0x17  # MAX21100 (MAX21105: FIFO_STORE)
    FIFO_CFG = 0x18  # MAX21100 (MAX21105: FIFO_THS; its FIFO_CFG is 0x19)
    # common bank
    WHO_AM_I = 0x20
    REVISION = 0x21
    BANK_SELECT = 0x22
    SYSTEM_STATUS = 0x23
    GYRO_X_H = 0x24
    ACC_X_H = 0x2A
    MAG_X_H = 0x30  # MAX21100 only (MAX21105 has TEMP here)
    FIFO_COUNT = 0x3C
    FIFO_STATUS = 0x3D
    FIFO_DATA = 0x3E
    RST_REG = 0x3F


class Status(IntEnum):
    """SYSTEM_STATUS (0x23) bits [V]. Mag/quaternion bits are in conflict between sources
    and are not used."""

    GYRO_DR = 0x01
    GYRO_ERR = 0x02
    ACC_DR = 0x04
    ACC_ERR = 0x08


# Address byte (facts section 5): bit7 = 1 read; bit6 = 1 *no* auto-increment (default
# if_parity=00); bits 5:0 the register. Multi-byte accesses leave bit6 clear.
ADDRESS_MASK = 0x3F
READ_BIT = 0x80
NO_INCREMENT_BIT = 0x40

SPI_CONVENTION = RegisterConvention(read_set=READ_BIT, single_set=NO_INCREMENT_BIT)
"""SPI: read flag in bit 7; single accesses say 'no increment' in bit 6."""
I2C_CONVENTION = RegisterConvention()
"""I2C: plain register byte (bit 6 keeps its meaning there, but a single access does not
care whether the pointer moves afterwards)."""


def convention_for(kind: BusKind) -> RegisterConvention:
    return SPI_CONVENTION if kind is BusKind.SPI else I2C_CONVENTION


RST_SW_RESET = 0x08
"""RST_REG bit 3: soft reset (registers back to power-on defaults)."""
I2C_CFG_I2C_OFF = 0x01
"""I2C_CFG/MIF_CFG bit 0: disable the I2C slave (recommended when on SPI)."""
I2C_CFG_LITTLE_ENDIAN = 0x02
"""I2C_CFG/MIF_CFG bit 1: data registers little-endian (driver keeps the big-endian default)."""
DR_CFG_TEMP_EN = 0x01
"""DR_CFG bit 0: temperature sensor enabled."""
DR_CFG_CLEAR_SHIFT = 2
"""DR_CFG [3:2]: data-ready clear mode: 0 after all data of a channel read, 1 any byte read,
2 on status read."""
DR_CFG_ONESHOT_MASK = 0x30
DR_CFG_ONESHOT_WRITE = 0x10
DR_CFG_ONESHOT_READ = 0x30
"""MAX21100 DR_CFG [5:4]: one-shot aux-master byte transaction trigger, 01 write, 11 read
[SS: har-in-air 0x15 / 0x35 then 0x05]; the other bits keep their meaning."""

# MAX21100 slave auto-read (facts section 6, "MAX21100 I2C master reading an HMC5883L" steps
# 4-5). [V] (har-in-air 0x86 for the HMC5883L, Kris Winer 0xC6 for the LSB-first LIS3MDL):
# MAG_SLV_CFG bit 7 enable, bit 6 byte-order swap, the low bits the byte count; MAG_MAP_REG
# 0x08 remaps the HMC5883L's X, Z, Y register order to X, Y, Z and 0x00 keeps the order read;
# ACC_CFG2 [3:1] = 0 samples the slave at the accelerometer rate. [SS] (one more code base,
# an mraa MAX21100 + HMC5983 driver, names the fields): MAG_SLV_CFG bit 5 MAG_SAFE, bit 4
# MAG_GRP, bit 3 I2C_STD (400 kHz when 0), [2:0] MAG_I2C_LEN; MAG_MAP_REG [5:3] MAG_CH_MAP
# (0 = A, B, C; 1 = A, C, B), [2:0] INV_Z, INV_Y, INV_X; ACC_CFG2 [3:1] "SNS_MAG_ODR =
# ACC_ODR / 2^code".
MAG_SLV_CFG_ENABLE = 0x80
MAG_SLV_CFG_SWAP = 0x40
"""Set: the slave sends each word LSB first (the master swaps the pair)."""
MAG_SLV_CFG_LENGTH_MASK = 0x07
MAG_MAP_AS_READ = 0x00
"""MAG_MAP_REG: MAG X, Y, Z = the slave's first, second and third word, none inverted."""
MAG_MAP_SHIFT = 3
MAG_MAP_INVERT_MASK = 0x07
ACC_CFG2_MAG_RATE_SHIFT = 1
ACC_CFG2_MAG_RATE_MASK = 0x0E
"""ACC_CFG2 [3:1]: the slave is read every 2^code accelerometer measurements (0: each)."""
MAG_DATA_BYTES = 6
"""MAG X, Y, Z (0x30..0x35): the most the master keeps of a slave's data."""

# MAX21100 FIFO (facts section 6: addresses [V]; the rest [SS] from Kris Winer's MAX21100
# sketch, calibrateMAX21100, or [UNVERIFIED] from the MAX21105's user guide, section 5; the
# reader, imuhal_chips.max2110x.fifo, states each assumption once).
FIFO_CFG_NORMAL = 0x40
"""FIFO_CFG [7:6] = 01: normal mode (Winer's 0x41 / 0x42 "FIFO normal mode"); 00 off."""
FIFO_CFG_STORE_GYRO = 0x01
"""FIFO_CFG bit 0: gyro words stored (Winer's 0x41 "accumulate gyro data")."""
FIFO_CFG_STORE_ACCEL = 0x02
"""FIFO_CFG bit 1: accelerometer words stored (Winer's 0x42)."""
FIFO_STATUS_DATA_LOST = 0x10
"""FIFO_STATUS bit 4 data_lost [UNVERIFIED: the MAX21105's bit; Winer uses bit 2, the
threshold, which is the MAX21105's ovthold too]."""
FIFO_DEPTH_WORDS = 64
"""Winer: "128 bytes in the FIFO = 64 words" [SS]; the MAX21105's (single size) is not in
its facts and is taken to be the same [UNVERIFIED]."""
FIFO_FRAME_WORDS = 6
"""Gyro X, Y, Z then accel X, Y, Z per frame, big-endian [UNVERIFIED: the MAX21105's
layout]; FIFO_COUNT counts words (Winer: "fifo_count/3" three-axis samples) [SS]."""



@dataclass(frozen=True)
class FifoRegisters:
    """Where a part keeps its FIFO's settings in bank 0, and what read: fifo writes there."""

    cfg: int
    """FIFO_CFG's address."""
    cfg_on: int
    """FIFO_CFG for normal mode, gyro + accel frames, a full FIFO writing no more."""
    threshold: int
    threshold_unit_words: int
    """Words per unit of the threshold register."""
    store: int | None = None
    """FIFO_STORE's address (MAX21105); None: the store bits are in FIFO_CFG."""
    store_value: int = 0

    def plan(self, frames: int) -> dict[int, int]:
        """The registers (address -> value, in write order) for a threshold of ``frames``
        gyro + accel frames; FIFO_CFG last, so the FIFO starts with everything set."""
        out = {} if self.store is None else {self.store: self.store_value}
        out[self.threshold] = frames * FIFO_FRAME_WORDS // self.threshold_unit_words
        out[self.cfg] = self.cfg_on
        return out


MAX21100_FIFO = FifoRegisters(
    cfg=Reg.FIFO_CFG, threshold=Reg.FIFO_TH, threshold_unit_words=1,
    cfg_on=FIFO_CFG_NORMAL | FIFO_CFG_STORE_GYRO | FIFO_CFG_STORE_ACCEL)
"""FIFO_TH 0x17 in words, FIFO_CFG 0x18 with the store bits (Winer's 0x41 | 0x42) [SS]."""
MAX21105_FIFO = FifoRegisters(
    cfg=0x19, threshold=0x18, threshold_unit_words=3, store=0x17, store_value=0x03,
    cfg_on=0x08)
"""The MAX21105 user guide's (facts section 5) [DS]: FIFO_STORE 0x17 ([1] accel, [0] gyro),
FIFO_THS 0x18 in samples (3-axis sets: 3 words), FIFO_CFG 0x19 [4:3] = 01 normal mode,
single size, [1] interrupt mode and [0] overrun clear (a full FIFO writes no more: the
oldest frames stay whole)."""

INT1_DATA_READY_PLAN: Mapping[int, int] = {
    0x17: 0x20,  # INT_SRC_SEL: the gyro's data-ready (har-in-air's MAX21105 value)
    0x0F: 0x80,  # INT_MSK
    0x0C: 0x00,  # INT_TMO_CFG: unlatched (a pulse)
    0x0B: 0x20,  # INT_CFG_2: INT1 enabled
}
"""Bank 1, read: fifo: INT1 pulses at each gyro measurement, the data-ready line a profile's
``interrupt:`` takes. The MAX21105 user guide's DATA_READY interrupt example (facts section
5) with har-in-air's gyro-only source [DS+SS], taken for the MAX21100, whose bank 1 has its
interrupt registers at the same addresses (INT_SRC_SEL 0x17 [V]) but whose bits no source
describes [UNVERIFIED]."""

# --- setting tables: physical value -> code (and sensitivity) ------------------------------

GYRO_RANGE_DPS: Mapping[int, tuple[int, float]] = {
    # dps: (GYRO_CFG1[1:0], LSB per dps)
    2000: (0b00, 15.0),
    1000: (0b01, 30.0),
    500: (0b10, 60.0),
    250: (0b11, 120.0),
}

GYRO_BANDWIDTH_HZ: Mapping[float, int] = {
    # GYRO_CFG1[5:2], normal (non-OIS) mode; same table on both parts
    bw: code
    for code, bw in enumerate(
        (2, 4, 6, 8, 10, 14, 22, 32, 50, 75, 100, 150, 200, 250, 300, 400)
    )
}

ACCEL_RANGE_G: Mapping[int, tuple[int, float]] = {
    # g: (PWR_ACC_CFG[7:6], LSB per g)
    16: (0b00, 1875.0),
    8: (0b01, 3750.0),
    4: (0b10, 7500.0),
    2: (0b11, 15000.0),
}

ACCEL_LPF_DIVISOR: Mapping[int, int] = {
    # ODR divisor: ACC_CFG1[5:4]; 48 is the strongest low-pass filtering
    48: 0b00,
    22: 0b01,
    9: 0b10,
    3: 0b11,
}

MAX21100_GYRO_ODR_HZ: Mapping[float, int] = {
    hz: code
    for code, hz in enumerate(
        (8000, 4000, 2000, 1000, 500, 250, 125, 62.5, 31.25, 15.625, 7.8125, 3.90625)
    )
}
MAX21100_ACCEL_ODR_HZ: Mapping[float, int] = {
    hz: code for code, hz in enumerate((2000, 1000, 500, 250, 125, 62.5, 31.25))
}
MAX21105_GYRO_ODR_HZ: Mapping[float, int] = {
    hz: code for code, hz in enumerate((8000, 4000, 2000, 800, 400, 200, 100, 50, 25, 10))
}
MAX21105_ACCEL_ODR_HZ: Mapping[float, int] = {
    hz: code for code, hz in enumerate((2000, 800, 400, 200, 100, 50, 25, 10, 5))
}

POWER_MODE_SHIFT = 3
POWER_MODE_ACC_GYRO_NORMAL = 0b1111
"""POWER_CFG [6:3] = 15: accelerometer and gyroscope in normal (low-noise) mode."""
GYRO_ON_MODES = frozenset({0b0010, 0b0011, 0b1110, 0b1111})
"""Power modes in which the gyro measures (spot/low-power or normal)."""
ACCEL_ON_MODES = frozenset({0b1000, 0b1100, 0b1101, 0b1110, 0b1111})



@dataclass(frozen=True)
class PartSpec:
    """What differs between MAX21100 and MAX21105."""

    part: str
    driver: str
    who_am_i: int
    revision: int
    gyro_odr_hz: Mapping[float, int]
    accel_odr_hz: Mapping[float, int]
    temp_register: int
    power_cfg_on: int
    """POWER_CFG value for 'accel + gyro normal' (MAX21100 adds the gyro X/Y/Z enables)."""
    accel_axes_enable: int
    """Bits OR-ed into PWR_ACC_CFG (MAX21100: X/Y/Z enable in [2:0]; MAX21105: RFU = 0)."""
    has_aux_master: bool
    fifo: FifoRegisters
    bank0_defaults: Mapping[int, int] = field(default_factory=dict)
    """Power-on values of bank-0 registers that are not 0x00 (emulator)."""

    def register_name(self, reg: int) -> str:
        """A bank-0 or common register's name on this part (the FIFO's differ)."""
        if self.fifo.store is not None:
            fifo = {self.fifo.store: "FIFO_STORE", self.fifo.threshold: "FIFO_THS",
                    self.fifo.cfg: "FIFO_CFG"}
            if reg in fifo:
                return fifo[reg]
        return Reg(reg).name

    @property
    def burst_start(self) -> int:
        return Reg.SYSTEM_STATUS

    @property
    def burst_length(self) -> int:
        """SYSTEM_STATUS through TEMP_L: one transaction carries status and every word."""
        return self.temp_register + 2 - Reg.SYSTEM_STATUS


MAX21100 = PartSpec(
    part="MAX21100",
    driver="max21100",
    who_am_i=0xB2,
    revision=0x01,  # [UNVERIFIED] value; only the address is known
    gyro_odr_hz=MAX21100_GYRO_ODR_HZ,
    accel_odr_hz=MAX21100_ACCEL_ODR_HZ,
    temp_register=0x36,
    power_cfg_on=(POWER_MODE_ACC_GYRO_NORMAL << POWER_MODE_SHIFT) | 0x07,  # 0x7F
    accel_axes_enable=0x07,
    has_aux_master=True,
    fifo=MAX21100_FIFO,
    # Gyro BW 100 Hz default [V]; FS field default assumed as on the MAX21105 (2000 dps);
    # gyro ODR 500 Hz and accel ODR 125 Hz defaults [V]; accel FS default assumed 2 g.
    bank0_defaults={0x01: 0x28, 0x02: 0x04, 0x04: 0xC0, 0x05: 0x04, 0x13: DR_CFG_TEMP_EN},
)

MAX21105 = PartSpec(
    part="MAX21105",
    driver="max21105",
    who_am_i=0xB4,
    revision=0x05,  # SILICON_REV_OTP default [V]
    gyro_odr_hz=MAX21105_GYRO_ODR_HZ,
    accel_odr_hz=MAX21105_ACCEL_ODR_HZ,
    temp_register=0x30,
    power_cfg_on=POWER_MODE_ACC_GYRO_NORMAL << POWER_MODE_SHIFT,  # 0x78
    accel_axes_enable=0x00,
    has_aux_master=False,
    fifo=MAX21105_FIFO,
    # SNS_CFG_1 0x28 (100 Hz, 2000 dps), SNS_CFG_2 400 Hz, accel 2 g, accel ODR 400 Hz,
    # ACC_CFG_2 output LPF, temperature enabled [DS].
    bank0_defaults={0x01: 0x28, 0x02: 0x04, 0x04: 0xC0, 0x05: 0x02, 0x06: 0x40, 0x13: 0x01},
)

PARTS_BY_WHO_AM_I = {MAX21100.who_am_i: MAX21100, MAX21105.who_am_i: MAX21105}


@dataclass(frozen=True)
class Scales:
    """The active conversion factors, cached by the driver after configure()."""

    gyro_lsb_per_dps: float
    accel_lsb_per_g: float



def gyro_cfg1(range_dps: int, bandwidth_hz: float) -> int:
    return (GYRO_BANDWIDTH_HZ[bandwidth_hz] << 2) | GYRO_RANGE_DPS[range_dps][0]


def pwr_acc_cfg(spec: PartSpec, range_g: int) -> int:
    return (ACCEL_RANGE_G[range_g][0] << 6) | spec.accel_axes_enable


def acc_cfg1(spec: PartSpec, lpf_divisor: int, odr_hz: float) -> int:
    return (ACCEL_LPF_DIVISOR[lpf_divisor] << 4) | spec.accel_odr_hz[odr_hz]


def gyro_range_from_code(cfg1: int) -> int:
    code = cfg1 & 0x03
    return next(r for r, (c, _) in GYRO_RANGE_DPS.items() if c == code)


def accel_range_from_code(pwr_acc: int) -> int:
    code = (pwr_acc >> 6) & 0x03
    return next(r for r, (c, _) in ACCEL_RANGE_G.items() if c == code)


def odr_from_code(table: Mapping[float, int], code: int) -> float | None:
    """The ODR for a code (None when the code is reserved)."""
    for hz, c in table.items():
        if c == code:
            return float(hz)
    return None
