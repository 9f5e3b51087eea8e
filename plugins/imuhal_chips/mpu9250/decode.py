"""MPU-9250 sample decoding as pure functions: big-endian counts -> SI in the sensor frame.

The burst ACCEL_XOUT_H..GYRO_ZOUT_L (0x3B..0x48) holds accel X, Y, Z, temperature, gyro X,
Y, Z as signed 16-bit big-endian words. The accelerometer measures specific force (a chip
lying flat, face up, reads +1 g on Z), which is what imuhal's accel channel carries, so the
sign is kept; only the unit changes: counts / (LSB/g) * 9.80665 m/s^2. Gyro: counts /
(LSB/(deg/s)) in rad/s. Temperature: counts / 333.87 + 21 degC.
"""

from __future__ import annotations

import math
import struct
from dataclasses import dataclass

from imuhal_chips.mpu9250.registers import (
    STANDARD_GRAVITY_M_S2,
    TEMP_LSB_PER_DEGC,
    TEMP_OFFSET_DEGC,
)

COUNT_MIN, COUNT_MAX = -32768, 32767


@dataclass(frozen=True)
class RawSample:
    accel: tuple[int, int, int]
    temperature: int
    gyro: tuple[int, int, int]


def decode_counts(data: bytes) -> RawSample:
    """Split the 14 bytes 0x3B..0x48 into accel, temperature and gyro counts."""
    if len(data) != 14:
        raise ValueError(f"MPU-9250 sample burst is 14 bytes, got {len(data)}")
    ax, ay, az, t, gx, gy, gz = struct.unpack(">7h", bytes(data))
    return RawSample((ax, ay, az), t, (gx, gy, gz))


def accel_m_s2(counts: tuple[int, int, int], lsb_per_g: float) -> tuple[float, float, float]:
    k = STANDARD_GRAVITY_M_S2 / lsb_per_g
    return (counts[0] * k, counts[1] * k, counts[2] * k)


def gyro_rad_s(counts: tuple[int, int, int], lsb_per_dps: float) -> tuple[float, float, float]:
    k = math.radians(1.0) / lsb_per_dps
    return (counts[0] * k, counts[1] * k, counts[2] * k)


def temperature_degc(count: int) -> float:
    return count / TEMP_LSB_PER_DEGC + TEMP_OFFSET_DEGC


def saturated(counts: tuple[int, ...]) -> bool:
    """True when any axis sits at the 16-bit limit: the true value may be larger."""
    return any(c in (COUNT_MIN, COUNT_MAX) for c in counts)
