"""HMC5883L (Honeywell 3-axis magnetometer) register map and setting tables.

Source: HMC5883L datasheet Form 900405 Rev E (Feb 2013), cross-checked with Linux
drivers/iio/magnetometer/hmc5843_core.c (facts/chips.md section 3, chip-vectors.json).
"""

from __future__ import annotations

from collections.abc import Mapping
from enum import IntEnum

I2C_ADDRESS = 0x1E
"""7-bit I2C address (fixed; no address pins)."""
IDENTITY = b"H43"
"""ID registers A, B, C (0x0A..0x0C)."""

UT_PER_GAUSS = 100.0
"""1 gauss = 100 microtesla."""

DATA_MIN, DATA_MAX = -2048, 2047
"""Valid data register range (0xF800..0x07FF)."""
OVERFLOW_VALUE = -4096
"""An axis reads -4096 (0xF000) after ADC over/underflow until the next valid measurement."""


class Reg(IntEnum):
    CONFIG_A = 0x00
    CONFIG_B = 0x01
    MODE = 0x02
    X_MSB = 0x03
    X_LSB = 0x04
    Z_MSB = 0x05  # the HMC5883L stores Z *before* Y
    Z_LSB = 0x06
    Y_MSB = 0x07
    Y_LSB = 0x08
    STATUS = 0x09
    ID_A = 0x0A
    ID_B = 0x0B
    ID_C = 0x0C


DATA_FIRST, DATA_LAST = Reg.X_MSB, Reg.Y_LSB
POINTER_WRAP_TO = Reg.X_MSB
"""After register 8 (Y_LSB) is read the pointer returns to register 3."""
LAST_REGISTER = Reg.ID_C

STATUS_RDY = 0x01
STATUS_LOCK = 0x02

# Config A fields
CRA_AVERAGING_SHIFT = 5
CRA_RATE_SHIFT = 2
CRA_MEAS_MASK = 0x03  # 00 normal, 01 positive bias, 10 negative bias
CRA_WRITABLE = 0x7F  # bit 7 must be 0
# Config B: gain in [7:5]; [4:0] must be 0
CRB_GAIN_SHIFT = 5
CRB_WRITABLE = 0xE0
# Mode register
MODE_CONTINUOUS = 0b00
MODE_SINGLE = 0b01
MODE_IDLE = 0b11  # 10 and 11 are both idle; the chip shows 11 after a single measurement
MODE_MD_MASK = 0x03
MODE_WRITABLE = 0x83  # HS bit 7 and MD [1:0]

POWER_ON_DEFAULTS: Mapping[int, int] = {Reg.CONFIG_A: 0x10, Reg.CONFIG_B: 0x20,
                                         Reg.MODE: MODE_SINGLE}

RANGE_GAUSS: Mapping[float, tuple[int, float]] = {
    # recommended field range +/-Ga: (GN code, gain LSB/Ga)
    0.88: (0, 1370.0),
    1.3: (1, 1090.0),
    1.9: (2, 820.0),
    2.5: (3, 660.0),
    4.0: (4, 440.0),
    4.7: (5, 390.0),
    5.6: (6, 330.0),
    8.1: (7, 230.0),
}
GAIN_BY_CODE = {code: gain for code, gain in RANGE_GAUSS.values()}

ODR_HZ: Mapping[float, int] = {
    # continuous-mode output rate Hz: DO code (7 is reserved)
    0.75: 0, 1.5: 1, 3: 2, 7.5: 3, 15: 4, 30: 5, 75: 6,
}
ODR_BY_CODE = {code: hz for hz, code in ODR_HZ.items()}

AVERAGING: Mapping[int, int] = {1: 0b00, 2: 0b01, 4: 0b10, 8: 0b11}
"""Samples averaged per output: MA code."""

SINGLE_MEASUREMENT_NS = 6_000_000
"""Single-measurement mode: data ready about 6 ms after the mode write."""



def config_a(averaging: int, odr_hz: float) -> int:
    """Config A for normal measurement (no bias) at ``odr_hz`` averaging ``averaging``."""
    return (AVERAGING[averaging] << CRA_AVERAGING_SHIFT) | (ODR_HZ[odr_hz] << CRA_RATE_SHIFT)


def config_b(range_gauss: float) -> int:
    return RANGE_GAUSS[range_gauss][0] << CRB_GAIN_SHIFT


def gain_from_config_b(crb: int) -> float:
    """Gain in LSB/gauss for a Config B value."""
    return GAIN_BY_CODE[(crb >> CRB_GAIN_SHIFT) & 0x07]
