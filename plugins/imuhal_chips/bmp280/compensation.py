"""BMP280 trimming and compensation as pure functions, bit-exact to the datasheet.

Source: Bosch BMP280 datasheet BST-BMP280-DS001-19, section 3.11.3 (32-bit temperature and
64-bit pressure), appendix 8.1 (double) and 8.2 (32-bit pressure); worked example of rev 1.14
section 3.12. Every ``>>`` is an arithmetic (floor) shift, as in the datasheet and Linux
``bmp280-core.c``; Bosch's own driver v3.3.4 replaced the shifts by truncating ``/`` and so
differs in the last digit (t_fine 128423 instead of 128422 for the worked example). The one
true division in the 64-bit path truncates toward zero, as C does. The 32-bit pressure path
wraps to int32/uint32 after every operation, as the C code does on a 32-bit machine.

Inputs are raw 20-bit ADC counts; outputs are degC x 100 (int), Pa x 256 (Q24.8, int) or Pa.
The emulator encodes true values with its own code (``emulator_encoding``), never this module.
"""

from __future__ import annotations

import struct
from dataclasses import dataclass

from imuhal_chips.bmp280.registers import CALIB_LENGTH


@dataclass(frozen=True)
class Trim:
    """The factory trimming words dig_T1..dig_P9 (T1 and P1 unsigned, the rest signed)."""

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

    @classmethod
    def from_bytes(cls, data: bytes) -> Trim:
        """Parse the 24 bytes read from 0x88..0x9F (little-endian words)."""
        if len(data) != CALIB_LENGTH:
            raise ValueError(f"BMP280 trimming is {CALIB_LENGTH} bytes, got {len(data)}")
        return cls(*struct.unpack("<Hhh" "Hhhhhhhhh", bytes(data)))

    def to_bytes(self) -> bytes:
        """The register image 0x88..0x9F of these words."""
        return struct.pack(
            "<Hhh" "Hhhhhhhhh",
            self.T1, self.T2, self.T3, self.P1, self.P2, self.P3,
            self.P4, self.P5, self.P6, self.P7, self.P8, self.P9,
        )

    def plausible(self) -> bool:
        """False for blank (all-zero) or floating (all-0xFF) trimming, which no part has."""
        return self.T1 not in (0, 0xFFFF) and self.P1 not in (0, 0xFFFF)


DATASHEET_TRIM = Trim(27504, 26435, -1000, 36477, -10685, 3024, 2855, 140, -7, 15500, -14600,
                      6000)
"""The worked example's trimming (datasheet rev 1.14 section 3.12)."""


def decode_adc(data: bytes) -> tuple[int, int]:
    """(adc_P, adc_T) from the 6 bytes 0xF7..0xFC: msb<<12 | lsb<<4 | xlsb>>4, unsigned."""
    if len(data) != 6:
        raise ValueError(f"BMP280 data burst is 6 bytes, got {len(data)}")
    press = (data[0] << 12) | (data[1] << 4) | (data[2] >> 4)
    temp = (data[3] << 12) | (data[4] << 4) | (data[5] >> 4)
    return press, temp


def encode_adc(adc: int) -> bytes:
    """The three data registers (msb, lsb, xlsb) holding a 20-bit ADC value."""
    return bytes([(adc >> 12) & 0xFF, (adc >> 4) & 0xFF, (adc & 0x0F) << 4])


# -- integer helpers ------------------------------------------------------------------------

def _i32(x: int) -> int:
    x &= 0xFFFFFFFF
    return x - (1 << 32) if x & 0x80000000 else x


def _u32(x: int) -> int:
    return x & 0xFFFFFFFF


def _cdiv(a: int, b: int) -> int:
    """C integer division: truncates toward zero."""
    q = abs(a) // abs(b)
    return q if (a >= 0) == (b >= 0) else -q


# -- temperature ----------------------------------------------------------------------------

def compensate_temperature_int32(adc_t: int, trim: Trim) -> tuple[int, int]:
    """(T in degC x 100, t_fine) by the datasheet's 32-bit integer formula."""
    var1 = (((adc_t >> 3) - (trim.T1 << 1)) * trim.T2) >> 11
    d = (adc_t >> 4) - trim.T1
    var2 = (((d * d) >> 12) * trim.T3) >> 14
    t_fine = _i32(var1 + var2)
    return (t_fine * 5 + 128) >> 8, t_fine


def compensate_temperature_double(adc_t: int, trim: Trim) -> tuple[float, int]:
    """(T in degC, t_fine) by the datasheet's double formula (appendix 8.1)."""
    var1 = (adc_t / 16384.0 - trim.T1 / 1024.0) * trim.T2
    var2 = (adc_t / 131072.0 - trim.T1 / 8192.0) ** 2 * trim.T3
    return (var1 + var2) / 5120.0, int(var1 + var2)


# -- pressure -------------------------------------------------------------------------------

def compensate_pressure_int64(adc_p: int, t_fine: int, trim: Trim) -> int:
    """Pressure in Pa x 256 (Q24.8) by the datasheet's 64-bit integer formula; 0 if invalid."""
    var1 = t_fine - 128000
    var2 = var1 * var1 * trim.P6
    var2 = var2 + ((var1 * trim.P5) << 17)
    var2 = var2 + (trim.P4 << 35)
    var1 = ((var1 * var1 * trim.P3) >> 8) + ((var1 * trim.P2) << 12)
    var1 = (((1 << 47) + var1) * trim.P1) >> 33
    if var1 == 0:
        return 0  # avoids a division by zero (the datasheet's guard)
    p = 1048576 - adc_p
    p = _cdiv(((p << 31) - var2) * 3125, var1)
    var1 = (trim.P9 * (p >> 13) * (p >> 13)) >> 25
    var2 = (trim.P8 * p) >> 19
    return ((p + var1 + var2) >> 8) + (trim.P7 << 4)


def compensate_pressure_int32(adc_p: int, t_fine: int, trim: Trim) -> int:
    """Pressure in Pa by the datasheet's 32-bit formula (appendix 8.2), with C wraparound."""
    var1 = _i32((t_fine >> 1) - 64000)
    q = _i32((var1 >> 2) * (var1 >> 2))
    var2 = _i32((q >> 11) * trim.P6)
    var2 = _i32(var2 + _i32(_i32(var1 * trim.P5) << 1))
    var2 = _i32((var2 >> 2) + _i32(trim.P4 << 16))
    var1 = _i32(
        (_i32(_i32(trim.P3 * (q >> 13)) >> 3) + (_i32(trim.P2 * var1) >> 1)) >> 18
    )
    var1 = _i32(_i32((32768 + var1) * trim.P1) >> 15)
    if var1 == 0:
        return 0
    p = _u32(_u32(_u32(1048576 - adc_p) - _u32(var2 >> 12)) * 3125)
    p = _u32((p << 1) // _u32(var1)) if p < 0x80000000 else _u32((p // _u32(var1)) * 2)
    var1 = _i32(_i32(trim.P9 * _i32(_u32((p >> 3) * (p >> 3)) >> 13)) >> 12)
    var2 = _i32(_i32(_i32(p >> 2) * trim.P8) >> 13)
    return _u32(_i32(_i32(p) + ((var1 + var2 + trim.P7) >> 4)))


def compensate_pressure_double(adc_p: int, t_fine: float, trim: Trim) -> float:
    """Pressure in Pa by the datasheet's double formula (appendix 8.1); 0.0 if invalid."""
    var1 = t_fine / 2.0 - 64000.0
    var2 = var1 * var1 * trim.P6 / 32768.0
    var2 = var2 + var1 * trim.P5 * 2.0
    var2 = var2 / 4.0 + trim.P4 * 65536.0
    var1 = (trim.P3 * var1 * var1 / 524288.0 + trim.P2 * var1) / 524288.0
    var1 = (1.0 + var1 / 32768.0) * trim.P1
    if var1 == 0.0:
        return 0.0
    p = 1048576.0 - adc_p
    p = (p - var2 / 4096.0) * 6250.0 / var1
    var1 = trim.P9 * p * p / 2147483648.0
    var2 = p * trim.P8 / 32768.0
    return p + (var1 + var2 + trim.P7) / 16.0
