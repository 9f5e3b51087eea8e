"""AK8963 (AKM) magnetometer register map and setting tables.

Source of the register facts: InvenSense MPU-9250 Register Map RM-MPU-9250A-00 rev 1.4,
section 5 (the AK8963 inside the MPU-9250), cross-checked with Linux
``drivers/iio/imu/inv_mpu6050/inv_mpu_magn.c`` (ASA formula, bits, axis orientation) and the
8/100 Hz continuous-mode rates used by har-in-air and Kris Winer's code; imuhal shared chip
facts, section 4.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Final

I2C_ADDRESS: Final = 0x0C

REG_WIA: Final = 0x00
REG_INFO: Final = 0x01
REG_ST1: Final = 0x02
REG_HXL: Final = 0x03
REG_ST2: Final = 0x09
REG_CNTL1: Final = 0x0A
REG_CNTL2: Final = 0x0B
REG_ASTC: Final = 0x0C
REG_I2CDIS: Final = 0x0F
REG_ASAX: Final = 0x10

WIA: Final = 0x48

ST1_DRDY: Final = 0x01
ST1_DOR: Final = 0x02
ST2_HOFL: Final = 0x08
ST2_BITM: Final = 0x10
CNTL1_BIT: Final = 0x10
CNTL2_SRST: Final = 0x01

MODE_POWER_DOWN: Final = 0b0000
MODE_SINGLE: Final = 0b0001
MODE_CONTINUOUS_1: Final = 0b0010
MODE_CONTINUOUS_2: Final = 0b0110
MODE_EXTERNAL_TRIGGER: Final = 0b0100
MODE_SELF_TEST: Final = 0b1000
MODE_FUSE_ROM: Final = 0b1111
MODE_MASK: Final = 0x0F

DATA_BURST_START: Final = REG_ST1
DATA_BURST_LENGTH: Final = 8
"""ST1, HXL..HZH, ST2 in one burst that ends at ST2 (0x09), which releases the data."""

MODE_CHANGE_S: Final = 100e-6
"""Wait after entering power-down before the next mode (datasheet: at least 100 us)."""
RESET_S: Final = 1e-3
"""Wait after a soft reset before the next access."""

OVERFLOW_SUM_UT: Final = 4912.0
"""HOFL is set when |X| + |Y| + |Z| reaches the measurement range (4912 uT)."""


@dataclass(frozen=True)
class Resolution:
    """One output resolution (CNTL1.BIT): sensitivity and the data range."""

    bits: int
    bit_code: int
    ut_per_lsb: float
    max_count: int


RESOLUTIONS: Final[dict[int, Resolution]] = {
    14: Resolution(14, 0, 0.6, 8190),
    16: Resolution(16, CNTL1_BIT, 0.15, 32760),
}
"""resolution_bits -> CNTL1.BIT code, uT per LSB before ASA adjustment, largest |count|."""

CONTINUOUS_MODES: Final[dict[int, int]] = {8: MODE_CONTINUOUS_1, 100: MODE_CONTINUOUS_2}
"""odr_hz -> CNTL1.MODE for continuous measurement."""

MODE_PERIOD_S: Final[dict[int, float]] = {MODE_CONTINUOUS_1: 1 / 8, MODE_CONTINUOUS_2: 1 / 100}

MEASUREMENT_S: Final = 7.2e-3
"""Single measurement time (max); DRDY follows a trigger by this long."""


def cntl1_value(odr_hz: int, resolution_bits: int) -> int:
    return RESOLUTIONS[resolution_bits].bit_code | CONTINUOUS_MODES[odr_hz]
