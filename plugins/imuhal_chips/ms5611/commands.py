"""MS5611-01BA03 command set and conversion timing, as data.

The MS5611 has no registers: every action is a one-byte command. This module states those
bytes and the per-oversampling-ratio (OSR) conversion times once, for the driver and the
emulator alike.

Source of facts: MS5611-01BA03 datasheet (DA5611-01BA03_011, Fig.4 command table, p.2
conversion-time table, Fig.5/6 reset sequence), cross-checked against the Linux IIO
``ms5611_core.c`` and Betaflight drivers; summarised in chips.md section 1.
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import Enum
from typing import Literal

Osr = Literal[256, 512, 1024, 2048, 4096]
"""An oversampling ratio the chip accepts."""

OSR_VALUES: tuple[int, ...] = (256, 512, 1024, 2048, 4096)

RESET = 0x1E
"""Reset: reloads the calibration PROM into the chip's internal register."""
ADC_READ = 0x00
"""ADC read: returns the 24-bit result of the last conversion, MSB first."""
PROM_READ_BASE = 0xA0
"""PROM read of word n (0..7) is ``PROM_READ_BASE + 2*n``; returns 16 bits, MSB first."""
CONVERT_BASE = 0x40
"""Convert = 0x40 | (type << 4) | (osr_index << 1); type 0 = D1 pressure, 1 = D2 temperature."""

PROM_WORDS = 8
ADC_READ_LEN = 3
PROM_READ_LEN = 2
ADC_MAX = (1 << 24) - 1

RESET_RELOAD_MS = 2.8
"""Time the chip needs after RESET to reload its PROM (datasheet Fig.5/6)."""
RESET_RELOAD_NS = 2_800_000


class Measurement(str, Enum):
    """What a conversion measures. D1 is the raw pressure, D2 the raw temperature."""

    D1 = "pressure"
    D2 = "temperature"

    @property
    def type_bit(self) -> int:
        return 0 if self is Measurement.D1 else 1


@dataclass(frozen=True)
class OsrTiming:
    """Conversion time of one OSR setting, in ms, per the datasheet table."""

    osr: int
    index: int
    """The Ad2..Ad0 / Os2..Os0 field value in the convert command."""
    min_ms: float
    typ_ms: float
    max_ms: float

    @property
    def typ_ns(self) -> int:
        return round(self.typ_ms * 1_000_000)

    @property
    def max_ns(self) -> int:
        return round(self.max_ms * 1_000_000)

    def convert_command(self, measurement: Measurement) -> int:
        return CONVERT_BASE | (measurement.type_bit << 4) | (self.index << 1)


OSR_TIMING: dict[int, OsrTiming] = {
    256: OsrTiming(256, 0, 0.48, 0.54, 0.60),
    512: OsrTiming(512, 1, 0.95, 1.06, 1.17),
    1024: OsrTiming(1024, 2, 1.88, 2.08, 2.28),
    2048: OsrTiming(2048, 3, 3.72, 4.13, 4.54),
    4096: OsrTiming(4096, 4, 7.40, 8.22, 9.04),
}


PRESSURE_RMS_PA: dict[int, float] = {256: 6.5, 512: 4.2, 1024: 2.7, 2048: 1.8, 4096: 1.2}
"""Datasheet RMS resolution of the compensated pressure per OSR (0.065 .. 0.012 mbar)."""


def convert_command(measurement: Measurement, osr: int) -> int:
    """The command byte that starts a ``measurement`` conversion at ``osr``."""
    return OSR_TIMING[osr].convert_command(measurement)


def prom_read_command(word: int) -> int:
    """The command byte that reads PROM word ``word`` (0..7)."""
    if not 0 <= word < PROM_WORDS:
        raise ValueError(f"MS5611 PROM word index must be 0..7, got {word}")
    return PROM_READ_BASE + 2 * word


@dataclass(frozen=True)
class Decoded:
    """A command byte decoded by what it asks the chip to do (used by the emulator)."""

    action: Literal["reset", "adc_read", "prom_read", "convert", "unknown"]
    measurement: Measurement | None = None
    osr: int | None = None
    word: int | None = None


_DECODE: dict[int, Decoded] = {
    RESET: Decoded("reset"),
    ADC_READ: Decoded("adc_read"),
    **{prom_read_command(n): Decoded("prom_read", word=n) for n in range(PROM_WORDS)},
    **{
        convert_command(m, osr): Decoded("convert", measurement=m, osr=osr)
        for m in Measurement
        for osr in OSR_VALUES
    },
}


_UNKNOWN = Decoded("unknown")


def decode_command(byte: int) -> Decoded:
    """What the chip does on receiving ``byte``; unlisted bytes decode as ``unknown``."""
    decoded = _DECODE.get(byte)
    return _UNKNOWN if decoded is None else decoded
