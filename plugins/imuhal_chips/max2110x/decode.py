"""Pure decoding of a MAX2110x status+data burst into SI values in the chip's sensor frame.

The burst starts at SYSTEM_STATUS (0x23) so the data-ready bits travel in the same
transaction as the words they describe:

    offset 0       SYSTEM_STATUS
    offset 1..6    GYRO X, Y, Z   (big-endian int16; 0x24..0x29)
    offset 7..12   ACC  X, Y, Z   (big-endian int16; 0x2A..0x2F)
    ...            MAG (MAX21100 only, 0x30..0x35, not decoded here)
    last 2 bytes   TEMP H, L      (0x30 on MAX21105, 0x36 on MAX21100)

Sensor frame: the axes printed on the chip (right-handed, Z out of the package top). The
accelerometer measures specific force: a chip lying level at rest reads +1 g on its Z axis.
"""

from __future__ import annotations

import math
import struct
from typing import NamedTuple

from imuhal_chips.max2110x.registers import (
    FULL_SCALE_COUNTS,
    STANDARD_GRAVITY_M_S2,
    TEMP_LSB_PER_DEGC,
    Status,
)

Counts3 = tuple[int, int, int]
Vec3 = tuple[float, float, float]

_SIX_WORDS = struct.Struct(">6h")
"""Gyro X, Y, Z then accel X, Y, Z: signed big-endian words, as a burst carries them."""
_GYRO_DR = int(Status.GYRO_DR)
_ACC_DR = int(Status.ACC_DR)
_OVERRUN = int(Status.GYRO_ERR | Status.ACC_ERR)


def be_int16(data: bytes, offset: int) -> int:
    """Signed big-endian 16-bit word at ``offset``."""
    return int.from_bytes(data[offset : offset + 2], "big", signed=True)


def words3(data: bytes, offset: int) -> Counts3:
    """Three consecutive big-endian int16 words (X, Y, Z)."""
    return (be_int16(data, offset), be_int16(data, offset + 2), be_int16(data, offset + 4))


def gyro_counts_to_rad_s(counts: Counts3, lsb_per_dps: float) -> Vec3:
    """Counts -> rad/s: counts / (LSB per dps) in deg/s, then to radians."""
    k = math.radians(1.0) / lsb_per_dps
    return (counts[0] * k, counts[1] * k, counts[2] * k)


def accel_counts_to_m_s2(counts: Counts3, lsb_per_g: float) -> Vec3:
    """Counts -> specific force in m/s^2 (1 g = 9.80665 m/s^2)."""
    k = STANDARD_GRAVITY_M_S2 / lsb_per_g
    return (counts[0] * k, counts[1] * k, counts[2] * k)


def temp_counts_to_degc(counts: int) -> float:
    """16-bit temperature counts -> degC (256 LSB/degC; 6400 counts = 25 degC)."""
    return counts / TEMP_LSB_PER_DEGC


def saturated(counts: Counts3) -> bool:
    """True when any axis sits at (or beyond) the nominal full scale of +/-30000 counts.

    The chip's words can hold up to +/-32767; what it outputs beyond the nominal range is
    not documented, so any value at or past +/-30000 is treated as possibly clipped.
    """
    x, y, z = counts  # written out: asked for every gyro and accelerometer reading
    full = FULL_SCALE_COUNTS
    return not (-full < x < full and -full < y < full and -full < z < full)


class Burst(NamedTuple):
    """One decoded status+data burst (raw counts; scale applied by the helpers above). A
    named tuple: one is built at every poll, faster than a frozen dataclass."""

    status: int
    gyro: Counts3
    accel: Counts3
    temperature: int

    @property
    def gyro_ready(self) -> bool:
        return bool(self.status & _GYRO_DR)

    @property
    def accel_ready(self) -> bool:
        return bool(self.status & _ACC_DR)

    @property
    def overrun(self) -> bool:
        """New data overwrote unread data (a sample was lost) on gyro or accel."""
        return bool(self.status & _OVERRUN)


def split_burst(data: bytes) -> Burst:
    """Split a burst read from SYSTEM_STATUS (see module docstring) into counts."""
    if len(data) < 15:
        raise ValueError(f"MAX2110x burst needs at least 15 bytes, got {len(data)}")
    gx, gy, gz, ax, ay, az = _SIX_WORDS.unpack_from(data, 1)
    return Burst(status=data[0], gyro=(gx, gy, gz), accel=(ax, ay, az),
                 temperature=be_int16(data, len(data) - 2))
