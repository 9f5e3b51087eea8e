"""BMP280 register map and setting tables (physical setting -> register code).

Source of the register facts: Bosch BMP280 datasheet BST-BMP280-DS001-19 rev 1.19 (register
map table 18, oversampling table 5/21, filter table 6/7, standby table 11, measurement time
section 3.8.1), cross-checked with Bosch BMP280_driver v3.3.4 ``bmp280_defs.h`` and Linux
``bmp280-core.c``; summarised in imuhal's shared chip facts, section 2.
"""

from __future__ import annotations

from typing import Final

# -- addresses -------------------------------------------------------------------------------
I2C_ADDRESSES: Final = (0x76, 0x77)
"""SDO to GND -> 0x76, SDO to VDDIO -> 0x77."""

REG_CALIB: Final = 0x88
CALIB_LENGTH: Final = 24
"""0x88..0x9F: dig_T1..dig_P9, little-endian 16-bit words (T1 and P1 unsigned)."""
REG_CHIP_ID: Final = 0xD0
REG_RESET: Final = 0xE0
REG_STATUS: Final = 0xF3
REG_CTRL_MEAS: Final = 0xF4
REG_CONFIG: Final = 0xF5
REG_PRESS_MSB: Final = 0xF7
REG_TEMP_MSB: Final = 0xFA

CHIP_ID: Final = 0x58
SAMPLE_CHIP_IDS: Final = (0x56, 0x57)
"""Engineering-sample ids the Bosch driver also accepts."""
RESET_COMMAND: Final = 0xB6

STATUS_MEASURING: Final = 0x08
STATUS_IM_UPDATE: Final = 0x01

MODE_SLEEP: Final = 0b00
MODE_FORCED: Final = 0b01
"""0b10 is also forced mode."""
MODE_NORMAL: Final = 0b11
MODE_MASK: Final = 0b11

ADC_SKIPPED: Final = 0x80000
"""What a skipped (oversampling 0) or never-run measurement reads as."""
ADC_MAX: Final = (1 << 20) - 1
ADC_BITS_FILTERED: Final = 20
"""Resolution of a filtered output word (datasheet 3.3.2/3.3.3: the IIR filter gives 20 bit)."""

POLL_BURST_START: Final = REG_STATUS
POLL_BURST_LENGTH: Final = 10
"""0xF3..0xFC: status, ctrl_meas, config, (0xF6 reserved), press[3], temp[3] in one burst."""

STARTUP_S: Final = 0.002
"""Time from power-on/soft reset until the NVM copy (im_update) is done (datasheet 2 ms)."""

# -- setting tables ---------------------------------------------------------------------------
OVERSAMPLING_CODES: Final[dict[int, int]] = {1: 0b001, 2: 0b010, 4: 0b011, 8: 0b100, 16: 0b101}
"""osrs_t / osrs_p code per oversampling factor (0b000 = skipped; 0b110/0b111 also mean x16)."""

OVERSAMPLING_BITS: Final[dict[int, int]] = {1: 16, 2: 17, 4: 18, 8: 19, 16: 20}
"""ADC resolution in bits per oversampling factor (the IIR filter raises it to 20)."""

PRESSURE_RESOLUTION_PA: Final[dict[int, float]] = {1: 2.62, 2: 1.31, 4: 0.66, 8: 0.33, 16: 0.16}
"""Datasheet table 5: pressure resolution per oversampling factor."""

IIR_CODES: Final[dict[int, int]] = {0: 0b000, 2: 0b001, 4: 0b010, 8: 0b011, 16: 0b100}
"""IIR filter coefficient (0 = off) -> config.filter code."""

STANDBY_CODES_MS: Final[dict[float, int]] = {
    0.5: 0b000, 62.5: 0b001, 125.0: 0b010, 250.0: 0b011,
    500.0: 0b100, 1000.0: 0b101, 2000.0: 0b110, 4000.0: 0b111,
}
"""Normal-mode standby time t_sb (ms) -> config.t_sb code."""


def oversampling_from_code(code: int) -> int:
    """Oversampling factor of an osrs code (0 = skipped); 0b101..0b111 all mean x16."""
    if code == 0:
        return 0
    return 1 << (min(code, 0b101) - 1)


def iir_from_code(code: int) -> int:
    """IIR coefficient of a filter code (0 = off); codes above 0b100 mean 16."""
    return 0 if code == 0 else 1 << min(code, 0b100)


def standby_ms_from_code(code: int) -> float:
    return {v: k for k, v in STANDBY_CODES_MS.items()}[code & 0b111]


def measurement_time_s(temperature_os: int, pressure_os: int, *, maximum: bool) -> float:
    """Conversion time of one measurement (datasheet 3.8.1), in seconds.

    typ = 1 + 2*osrs_t + (2*osrs_p + 0.5) ms; max = 1.25 + 2.3*osrs_t + (2.3*osrs_p + 0.575) ms.
    The pressure term is dropped when pressure is skipped (factor 0).
    """
    if maximum:
        ms = 1.25 + 2.3 * temperature_os + ((2.3 * pressure_os + 0.575) if pressure_os else 0.0)
    else:
        ms = 1.0 + 2.0 * temperature_os + ((2.0 * pressure_os + 0.5) if pressure_os else 0.0)
    return ms / 1000.0


def ctrl_meas_value(temperature_os: int, pressure_os: int, mode: int) -> int:
    return (OVERSAMPLING_CODES[temperature_os] << 5) | (OVERSAMPLING_CODES[pressure_os] << 2) | mode


def config_value(standby_ms: float, iir: int) -> int:
    """config register: [7:5] t_sb, [4:2] filter, [0] spi3w_en (always 0: 4-wire SPI)."""
    return (STANDBY_CODES_MS[standby_ms] << 5) | (IIR_CODES[iir] << 2)
