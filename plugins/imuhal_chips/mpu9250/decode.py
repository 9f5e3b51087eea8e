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

import numpy as np
import numpy.typing as npt

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


def accel_scale(lsb_per_g: float) -> float:
    """m/s^2 per accelerometer count."""
    return STANDARD_GRAVITY_M_S2 / lsb_per_g


def gyro_scale(lsb_per_dps: float) -> float:
    """rad/s per gyro count."""
    return math.radians(1.0) / lsb_per_dps


def accel_m_s2(counts: tuple[int, int, int], lsb_per_g: float) -> tuple[float, float, float]:
    k = accel_scale(lsb_per_g)
    return (counts[0] * k, counts[1] * k, counts[2] * k)


def gyro_rad_s(counts: tuple[int, int, int], lsb_per_dps: float) -> tuple[float, float, float]:
    k = gyro_scale(lsb_per_dps)
    return (counts[0] * k, counts[1] * k, counts[2] * k)


def temperature_degc(count: int) -> float:
    return count / TEMP_LSB_PER_DEGC + TEMP_OFFSET_DEGC


def saturated(counts: tuple[int, ...]) -> bool:
    """True when any axis sits at the 16-bit limit: the true value may be larger."""
    return any(c in (COUNT_MIN, COUNT_MAX) for c in counts)


def frame_counts(frames: bytes, n: int) -> npt.NDArray[np.int16]:
    """``n`` frames of 14 bytes 0x3B..0x48 (a FIFO burst's, joined) as an (n, 7) array of
    counts: accel X, Y, Z, temperature, gyro X, Y, Z (what :func:`decode_counts` gives per
    frame)."""
    if len(frames) != 14 * n:
        raise ValueError(f"{n} MPU-9250 frames are {14 * n} bytes, got {len(frames)}")
    return np.frombuffer(frames, dtype=">i2").reshape(n, 7).astype(np.int16)


def saturated_rows(counts: npt.NDArray[np.int16]) -> npt.NDArray[np.bool_]:
    """Per row, :func:`saturated`: any axis at the 16-bit limit."""
    return ((counts == COUNT_MIN) | (counts == COUNT_MAX)).any(axis=1)
