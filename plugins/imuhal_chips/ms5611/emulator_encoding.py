"""What an MS5611's sensor element reports: true pressure and temperature -> D1/D2 counts.

Written from the datasheet side, independently of the driver's ``conversion`` module, so a
wrong fact in either one makes a driver-against-emulator test fail instead of cancelling:

- ``prom_crc4``: the AN520 PROM check as polynomial arithmetic over GF(2). AN520's C loop
  feeds the 16 bytes (word 7's low byte cleared) through a 16-bit register and keeps its top
  nibble; that equals the remainder of the 128-bit PROM image, shifted right by 4 bits, divided
  by the generator x^4 + x + 1.
- ``true_temperature_centi`` / ``true_pressure_pa``: the datasheet's forward formulas
  (Fig. 2 first order, Fig. 3 second order), written with Python's floor division ``//`` by
  the powers of two the datasheet prints ("/2^n" on a 32/64-bit integer).
- ``counts_for`` (``d1_for``, ``d2_for``: each alone): D1 and D2 for a true pressure and
  temperature, solved in closed form from the real-valued formulas (a quadratic for TEMP
  below 20 degC). D2 is then settled onto the integer formulas by stepping a few counts, so
  the chip reports the true temperature to its output resolution (0.01 degC); D1 is the
  real-valued count rounded, so it keeps the pressure's sub-pascal part (and its noise) as
  the element's 24-bit ADC does, and the compensated output is the nearest pascal.

Source: MS5611-01BA03 datasheet DA5611-01BA03_011 p.7-8; application note AN520 (CRC-4).
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

ADC_FULL = (1 << 24) - 1
"""Largest 24-bit ADC count; 0 is reserved by the protocol for "no conversion"."""

CRC4_GENERATOR = 0b1_0011
"""x^4 + x + 1 (AN520)."""


def _gf2_mod(value: int, generator: int) -> int:
    """Remainder of the GF(2) polynomial ``value`` divided by ``generator``."""
    degree = generator.bit_length() - 1
    while value.bit_length() > degree:
        value ^= generator << (value.bit_length() - 1 - degree)
    return value


def prom_crc4(words: Sequence[int]) -> int:
    """The CRC nibble AN520 defines for 8 PROM words (word 7's low byte excluded)."""
    image = 0
    for i, word in enumerate(words):
        word &= 0xFFFF
        if i == 7:
            word &= 0xFF00
        image = (image << 16) | word
    return _gf2_mod(image >> 4, CRC4_GENERATOR)


def prom_with_crc4(words: Sequence[int]) -> list[int]:
    """``words`` with word 7 bits 3..0 holding their CRC, as the factory programs them."""
    out = [w & 0xFFFF for w in words]
    out[7] = (out[7] & 0xFFF0) | prom_crc4(out)
    return out


@dataclass(frozen=True)
class PromCoefficients:
    """C1..C6 as the factory programmed them into PROM words 1..6."""

    sens_t1: int
    off_t1: int
    tcs: int
    tco: int
    t_ref: int
    tempsens: int

    @classmethod
    def of(cls, words: Sequence[int]) -> PromCoefficients:
        return cls(*(w & 0xFFFF for w in words[1:7]))


def _dt(c: PromCoefficients, d2: int) -> int:
    return d2 - c.t_ref * 256


def _temp_first_order(c: PromCoefficients, dt: int) -> int:
    return 2000 + dt * c.tempsens // 8_388_608  # 2^23


def true_temperature_centi(c: PromCoefficients, d2: int) -> int:
    """TEMP in 0.01 degC the datasheet's formulas give for ``d2`` (second order included)."""
    dt = _dt(c, d2)
    temp = _temp_first_order(c, dt)
    if temp < 2000:
        temp -= dt * dt // 2_147_483_648  # T2 = dT^2 / 2^31
    return temp


def _off_sens(c: PromCoefficients, d2: int) -> tuple[int, int]:
    dt = _dt(c, d2)
    temp = _temp_first_order(c, dt)
    off = c.off_t1 * 65_536 + c.tco * dt // 128  # C2 * 2^16 + C4 * dT / 2^7
    sens = c.sens_t1 * 32_768 + c.tcs * dt // 256  # C1 * 2^15 + C3 * dT / 2^8
    if temp < 2000:
        below = (temp - 2000) ** 2
        off2, sens2 = 5 * below // 2, 5 * below // 4
        if temp < -1500:
            far = (temp + 1500) ** 2
            off2 += 7 * far
            sens2 += 11 * far // 2
        off, sens = off - off2, sens - sens2
    return off, sens


def true_pressure_pa(c: PromCoefficients, d1: int, d2: int) -> int:
    """P in Pa (0.01 mbar) the datasheet's formulas give for ``d1`` and ``d2``."""
    off, sens = _off_sens(c, d2)
    return (d1 * sens // 2_097_152 - off) // 32_768  # (D1 * SENS / 2^21 - OFF) / 2^15


def _settle(value_of: Callable[[int], int], target: int, start: int) -> int:
    """The count in 1..ADC_FULL, near ``start``, whose non-decreasing ``value_of`` is closest
    to ``target`` (the lowest such count on a tie)."""
    lo, hi = 1, ADC_FULL
    n = min(max(start, lo), hi)
    # Bracket [n_low, n_high] with value(n_low) < target <= value(n_high), doubling steps.
    step = 1
    if value_of(n) >= target:
        high = n
        low = max(lo, n - step)
        while low > lo and value_of(low) >= target:
            high, step = low, step * 2
            low = max(lo, high - step)
        if value_of(low) >= target:
            return low
    else:
        low = n
        high = min(hi, n + step)
        while high < hi and value_of(high) < target:
            low, step = high, step * 2
            high = min(hi, low + step)
        if value_of(high) < target:
            return high
    while high - low > 1:
        mid = (low + high) // 2
        if value_of(mid) >= target:
            high = mid
        else:
            low = mid
    return low if target - value_of(low) < value_of(high) - target else high


def counts_for(c: PromCoefficients, pressure_pa: float, temperature_degc: float
               ) -> tuple[int, int]:
    """(D1, D2) the element reports for the true values, clamped to 1..2^24-1."""
    d2 = d2_for(c, temperature_degc)
    return _d1_for(c, pressure_pa, d2), d2


def d2_for(c: PromCoefficients, temperature_degc: float) -> int:
    """D2 alone, as :func:`counts_for` gives it (a temperature conversion needs no D1)."""
    want_t = round(temperature_degc * 100.0) if math.isfinite(temperature_degc) else (
        10**9 if temperature_degc > 0 else -10**9)
    return _d2_for(c, want_t)


def d1_for(c: PromCoefficients, pressure_pa: float, temperature_degc: float) -> int:
    """D1 alone, as :func:`counts_for` gives it (it depends on the temperature's D2)."""
    return _d1_for(c, pressure_pa, d2_for(c, temperature_degc))


def _d1_for(c: PromCoefficients, pressure_pa: float, d2: int) -> int:
    want_p = round(pressure_pa) if math.isfinite(pressure_pa) else (
        10**9 if pressure_pa > 0 else -10**9)
    off, sens = _off_sens(c, d2)
    if sens > 0 and math.isfinite(pressure_pa) and abs(pressure_pa) < 10**7:
        # P = (D1*SENS/2^21 - OFF)/2^15  =>  D1 = (P*2^15 + OFF) * 2^21 / SENS, in reals:
        # the count keeps the sub-pascal part of the pressure, as the element's ADC does
        # (about 50 counts per Pa), so its noise shows in D1 and a D1 word repeats only as
        # rarely as on the chip. Encoding P + 0.5 makes the floors of the integer formula
        # output the nearest pascal.
        d1_real = ((pressure_pa + 0.5) * 32_768 + off) * 2_097_152 / sens
        return min(max(round(d1_real), 1), ADC_FULL)
    # P = (D1*SENS/2^21 - OFF)/2^15  =>  D1 = (P*2^15 + OFF) * 2^21 / SENS
    guess_d1 = (math.ceil((want_p * 32_768 + off) * 2_097_152 / sens)
                if sens > 0 and abs(want_p) < 10**7 else ADC_FULL // 2)
    # true_pressure_pa(c, n, d2) with OFF and SENS of this D2 worked out once, not at every
    # step of the search (the same integer arithmetic).
    return _settle(lambda n: (n * sens // 2_097_152 - off) // 32_768, want_p, guess_d1)


@functools.lru_cache(maxsize=4096)
def _d2_for(c: PromCoefficients, want_t: int) -> int:
    """The D2 whose temperature is closest to ``want_t`` (0.01 degC); cached, since the
    board's temperature takes few distinct values in a run (a pure function of both)."""
    # TEMP = 2000 + dT*C6/2^23 (- dT^2/2^31 below 20 degC): solve for dT in reals.
    k = c.tempsens / 2**23
    if want_t >= 2000 or c.tempsens <= 0:
        dt_real = (want_t - 2000) / k if k else 0.0
    else:
        a = 1 / 2**31
        dt_real = (k - math.sqrt(k * k - 4 * a * (want_t - 2000))) / (2 * a)
    guess_d2 = c.t_ref * 256 + math.ceil(dt_real) if abs(dt_real) < 2**25 else ADC_FULL // 2
    return _settle(lambda n: true_temperature_centi(c, n), want_t, guess_d2)
