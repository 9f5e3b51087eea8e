"""What a BMP280's sensor element reports: true pressure and temperature -> 20-bit ADC values.

Written from the datasheet side, independently of the driver's ``compensation`` module (no
search over the driver's formulas): the datasheet's floating-point compensation (appendix
8.1) is a quadratic in adc_T for the temperature and, at a given temperature, a quadratic in
adc_P for the pressure, so both invert in closed form. A wrong trimming fact or formula in the
driver then shows as a wrong pressure or temperature in a driver-against-emulator test.

Source: Bosch BMP280 datasheet BST-BMP280-DS001-19 section 3.11.2 (trimming registers
0x88..0x9F, little-endian, T1/P1 unsigned) and appendix 8.1 (double-precision compensation).
"""

from __future__ import annotations

import math
import struct
from dataclasses import astuple, dataclass

T_FINE_PER_DEGC = 5120.0
"""T[degC] = t_fine / 5120 (appendix 8.1)."""


@dataclass(frozen=True)
class FactoryTrimming:
    """dig_T1..dig_P9 as programmed into the part's NVM."""

    T1: int
    T2: int
    T3: int
    P1: int
    P2: int
    P3: int
    P4: int
    P5: int
    P6: int
    P7: int
    P8: int
    P9: int

    def register_image(self) -> bytes:
        """Registers 0x88..0x9F: 12 little-endian words, T1 and P1 unsigned."""
        return struct.pack("<HhhHhhhhhhhh", *astuple(self))


DATASHEET_TRIMMING = FactoryTrimming(27504, 26435, -1000, 36477, -10685, 3024, 2855, 140, -7,
                                     15500, -14600, 6000)
"""The worked example's part (datasheet rev 1.14 section 3.12)."""


def t_fine_of(adc_t: float, k: FactoryTrimming) -> float:
    """The datasheet's t_fine for a temperature ADC value (real-valued)."""
    u = adc_t / 131072.0 - k.T1 / 8192.0
    return 8.0 * u * k.T2 + u * u * k.T3


def temperature_degc_of(adc_t: float, k: FactoryTrimming) -> float:
    return t_fine_of(adc_t, k) / T_FINE_PER_DEGC


def adc_t_for(temperature_degc: float, k: FactoryTrimming) -> float:
    """The (real) adc_T whose t_fine is ``temperature_degc * 5120``.

    With u = adc_T/2^17 - T1/2^13, t_fine = 8*T2*u + T3*u^2; the root taken is the one on the
    datasheet's monotone branch, in the cancellation-free form 2c / (b + sqrt(b^2 + 4ac')).
    """
    target = temperature_degc * T_FINE_PER_DEGC
    b = 8.0 * k.T2
    disc = b * b + 4.0 * k.T3 * target
    u = 2.0 * target / (b + math.copysign(math.sqrt(max(disc, 0.0)), b))
    return (u + k.T1 / 8192.0) * 131072.0


def _pressure_terms(t_fine: float, k: FactoryTrimming) -> tuple[float, float]:
    """(var1, var2) of appendix 8.1: the divisor and the offset at this temperature."""
    v1 = t_fine / 2.0 - 64000.0
    v2 = (v1 * v1 * k.P6 / 32768.0 + v1 * k.P5 * 2.0) / 4.0 + k.P4 * 65536.0
    v1 = (1.0 + (k.P3 * v1 * v1 / 524288.0 + k.P2 * v1) / 524288.0 / 32768.0) * k.P1
    return v1, v2


def pressure_pa_of(adc_p: float, t_fine: float, k: FactoryTrimming) -> float:
    """The datasheet's pressure for an ADC value at temperature ``t_fine``."""
    divisor, offset = _pressure_terms(t_fine, k)
    p = (1048576.0 - adc_p - offset / 4096.0) * 6250.0 / divisor
    return p + (k.P9 * p * p / 2147483648.0 + p * k.P8 / 32768.0 + k.P7) / 16.0


def adc_p_for(pressure_pa: float, t_fine: float, k: FactoryTrimming) -> float:
    """The (real) adc_P reporting ``pressure_pa`` at ``t_fine``: P = p + (P9 p^2/2^31 +
    P8 p/2^15 + P7)/16 is a quadratic in the intermediate p, which is linear in adc_P."""
    a = k.P9 / 2147483648.0 / 16.0
    b = 1.0 + k.P8 / 32768.0 / 16.0
    c = k.P7 / 16.0 - pressure_pa
    disc = b * b - 4.0 * a * c
    p = -2.0 * c / (b + math.sqrt(max(disc, 0.0)))
    divisor, offset = _pressure_terms(t_fine, k)
    return 1048576.0 - offset / 4096.0 - p * divisor / 6250.0
