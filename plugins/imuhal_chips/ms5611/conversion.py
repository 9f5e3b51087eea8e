"""MS5611-01BA03 PROM check and integer compensation, as pure functions.

- ``crc4`` / ``prom_is_valid``: the PROM integrity check of application note AN520.
- ``compensate``: raw D1 (pressure) and D2 (temperature) ADC counts to TEMP (0.01 degC) and
  P (Pa = 0.01 mbar), first and second order, in the datasheet's integer arithmetic. Every
  "/2^n" is an arithmetic right shift (floor), as in the Linux and Betaflight drivers whose
  published test vectors only reproduce with floor semantics; Python ``>>`` floors.
The emulator encodes true values with its own code (``emulator_encoding``), never this module.

Source of facts: MS5611-01BA03 datasheet (DA5611-01BA03_011) Fig.2 (first order) and Fig.3
(second order), AN520 (CRC4), Betaflight ``baro_ms5611_unittest.cc`` (vectors); summarised in
imuhal's chip-facts notes (chips.md section 1, chip-vectors.json "ms5611").
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

from imuhal_chips.ms5611.commands import PROM_WORDS

TEMP_MIN_CENTI_DEGC = -4000
TEMP_MAX_CENTI_DEGC = 8500
P_MIN_PA = 1000
P_MAX_PA = 120000
"""Datasheet operating range of the compensated outputs."""


def crc4(prom_words: Sequence[int]) -> int:
    """The AN520 CRC4 of the 8 PROM words (the nibble the chip stores in word 7 bits 3..0).

    The whole low byte of word 7 (serial low bits and the stored CRC) is cleared before the
    calculation; words are fed high byte first.
    """
    if len(prom_words) != PROM_WORDS:
        raise ValueError(f"MS5611 PROM has {PROM_WORDS} words, got {len(prom_words)}")
    words = [w & 0xFFFF for w in prom_words]
    words[7] &= 0xFF00
    remainder = 0
    for word in words:
        for byte in (word >> 8, word & 0xFF):
            remainder ^= byte
            for _ in range(8):
                # Polynomial x^4 + x + 1 aligned at bit 12 (its x^4 term falls off the top).
                if remainder & 0x8000:
                    remainder = ((remainder << 1) ^ 0x3000) & 0xFFFF
                else:
                    remainder = (remainder << 1) & 0xFFFF
    return (remainder >> 12) & 0xF


def stored_crc4(prom_words: Sequence[int]) -> int:
    """The CRC nibble the chip stored: word 7 bits 3..0."""
    return prom_words[7] & 0xF


def prom_is_valid(prom_words: Sequence[int]) -> bool:
    """True when the stored CRC4 matches and the PROM is not blank.

    All-0x0000 (CRC 0 matches stored 0) and all-0xFFFF PROMs are rejected regardless: they are
    what a bus stuck low or nothing answering looks like.
    """
    words = [w & 0xFFFF for w in prom_words]
    if all(w == 0x0000 for w in words) or all(w == 0xFFFF for w in words):
        return False
    return crc4(words) == stored_crc4(words)


def with_crc4(prom_words: Sequence[int]) -> list[int]:
    """A copy of ``prom_words`` with word 7's low nibble replaced by the correct CRC4."""
    words = [w & 0xFFFF for w in prom_words]
    words[7] = (words[7] & 0xFFF0) | crc4(words)
    return words


@dataclass(frozen=True)
class Coefficients:
    """Factory calibration C1..C6 (PROM words 1..6, unsigned 16-bit)."""

    c1: int
    """SENS_T1, pressure sensitivity."""
    c2: int
    """OFF_T1, pressure offset."""
    c3: int
    """TCS, temperature coefficient of pressure sensitivity."""
    c4: int
    """TCO, temperature coefficient of pressure offset."""
    c5: int
    """T_REF, reference temperature."""
    c6: int
    """TEMPSENS, temperature coefficient of the temperature."""

    @classmethod
    def from_prom(cls, prom_words: Sequence[int]) -> Coefficients:
        c = [w & 0xFFFF for w in prom_words[1:7]]
        return cls(*c)


@dataclass(frozen=True)
class Compensated:
    """The result of ``compensate``. Field names are the datasheet's, so values can be
    checked against its figures; ``_1st`` fields are before the second-order correction."""

    dT: int
    """Difference between actual and reference temperature, counts."""
    TEMP_1st: int
    OFF_1st: int
    SENS_1st: int
    P_1st: int
    T2: int
    OFF2: int
    SENS2: int
    TEMP: int
    """Temperature, 0.01 degC."""
    OFF: int
    """Offset at actual temperature."""
    SENS: int
    """Sensitivity at actual temperature."""
    P: int
    """Temperature-compensated pressure, Pa (0.01 mbar)."""

    @property
    def temperature_degc(self) -> float:
        return self.TEMP / 100.0

    @property
    def pressure_pa(self) -> float:
        return float(self.P)

    @property
    def temperature_in_range(self) -> bool:
        return TEMP_MIN_CENTI_DEGC <= self.TEMP <= TEMP_MAX_CENTI_DEGC

    @property
    def pressure_in_range(self) -> bool:
        return P_MIN_PA <= self.P <= P_MAX_PA


def _pressure(d1: int, sens: int, off: int) -> int:
    return (((d1 * sens) >> 21) - off) >> 15


def _temperature_terms(c: Coefficients, d2: int) -> tuple[int, int, int]:
    """(dT, first-order TEMP, T2) for raw D2: the TEMP is ``TEMP - T2``."""
    dt = d2 - (c.c5 << 8)
    temp = 2000 + ((dt * c.c6) >> 23)
    t2 = (dt * dt) >> 31 if temp < 2000 else 0
    return dt, temp, t2


def _offset_terms(c: Coefficients, dt: int, temp: int) -> tuple[int, int, int, int]:
    """(first-order OFF, first-order SENS, OFF2, SENS2) for dT and the first-order TEMP."""
    off = (c.c2 << 16) + ((c.c4 * dt) >> 7)
    sens = (c.c1 << 15) + ((c.c3 * dt) >> 8)
    off2 = sens2 = 0
    if temp < 2000:
        # OFF2/SENS2 use the first-order TEMP; the order of these steps is the datasheet's.
        low = (temp - 2000) ** 2
        off2 = (5 * low) >> 1
        sens2 = (5 * low) >> 2
        if temp < -1500:
            very_low = (temp + 1500) ** 2
            off2 += 7 * very_low
            sens2 += (11 * very_low) >> 1
    return off, sens, off2, sens2


def compensate(coeffs: Coefficients, d1: int, d2: int) -> Compensated:
    """Raw D1 (pressure) and D2 (temperature) counts -> compensated TEMP and P, datasheet
    integer arithmetic with floor shifts; second order applies below 20 degC."""
    c = coeffs
    dt, temp, t2 = _temperature_terms(c, d2)
    off, sens, off2, sens2 = _offset_terms(c, dt, temp)
    p_1st = _pressure(d1, sens, off)
    temp_2 = temp - t2
    off_2 = off - off2
    sens_2 = sens - sens2
    return Compensated(
        dT=dt,
        TEMP_1st=temp,
        OFF_1st=off,
        SENS_1st=sens,
        P_1st=p_1st,
        T2=t2,
        OFF2=off2,
        SENS2=sens2,
        TEMP=temp_2,
        OFF=off_2,
        SENS=sens_2,
        P=_pressure(d1, sens_2, off_2),
    )
