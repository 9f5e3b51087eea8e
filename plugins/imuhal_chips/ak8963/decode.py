"""AK8963 measurement decoding as pure functions: counts -> uT in the AK8963's own axes.

The AK8963 writes each axis little-endian (HXL before HXH), unlike the MPU-9250's big-endian
accel/gyro words. Each axis is scaled by the factory sensitivity adjustment read from fuse
ROM (ASAX..ASAZ): Hadj = H * ((ASA - 128) * 0.5 / 128 + 1) = H * (ASA + 128) / 256.

Axes (AK8963 sensor frame, as printed on its die) relative to the MPU-9250 accel/gyro axes:
mag X = accel Y, mag Y = accel X, mag Z = -accel Z. The driver outputs the AK8963 frame; the
profile's per-device mount rotation maps it to the body (see the package report for GY-91).
"""

from __future__ import annotations

import struct
from dataclasses import dataclass

from imuhal_chips.ak8963.registers import (
    RESOLUTIONS,
    ST1_DOR,
    ST1_DRDY,
    ST2_BITM,
    ST2_HOFL,
)


def asa_factor(asa: int) -> float:
    """Sensitivity adjustment factor of one fuse-ROM ASA byte: (ASA + 128) / 256."""
    if not 0 <= asa <= 0xFF:
        raise ValueError(f"ASA is an unsigned byte, got {asa}")
    return (asa + 128) / 256.0


@dataclass(frozen=True)
class Measurement:
    """One decoded burst ST1..ST2."""

    counts: tuple[int, int, int]
    field_ut: tuple[float, float, float]
    data_ready: bool
    data_overrun: bool
    overflow: bool
    """ST2.HOFL: the sum of the axes exceeded the range; the data are invalid."""
    saturated: bool
    """An axis sits at the data range limit (+-32760 16-bit, +-8190 14-bit)."""
    bits: int
    """Output resolution the chip reported in ST2.BITM."""


def decode_counts(data: bytes) -> tuple[int, int, int]:
    """Signed little-endian X, Y, Z from the 6 bytes HXL..HZH."""
    if len(data) != 6:
        raise ValueError(f"AK8963 data are 6 bytes, got {len(data)}")
    x, y, z = struct.unpack("<hhh", bytes(data))
    return x, y, z


def decode_burst(data: bytes, asa: tuple[int, int, int]) -> Measurement:
    """Decode the 8-byte burst ST1, HXL..HZH, ST2 with the fuse-ROM adjustment ``asa``.

    The sensitivity comes from ST2.BITM (the resolution the sample was taken with), so a
    sample is never scaled with another setting's LSB.
    """
    if len(data) != 8:
        raise ValueError(f"AK8963 burst ST1..ST2 is 8 bytes, got {len(data)}")
    st1, st2 = data[0], data[7]
    counts = decode_counts(data[1:7])
    resolution = RESOLUTIONS[16 if st2 & ST2_BITM else 14]
    lsb = resolution.ut_per_lsb
    field = tuple(c * lsb * asa_factor(a) for c, a in zip(counts, asa, strict=True))
    return Measurement(
        counts=counts,
        field_ut=(field[0], field[1], field[2]),
        data_ready=bool(st1 & ST1_DRDY),
        data_overrun=bool(st1 & ST1_DOR),
        overflow=bool(st2 & ST2_HOFL),
        saturated=any(abs(c) >= resolution.max_count for c in counts),
        bits=resolution.bits,
    )


def to_mpu9250_axes(v: tuple[float, float, float]) -> tuple[float, float, float]:
    """An AK8963-frame vector in the MPU-9250 accel/gyro axes: (m_y, m_x, -m_z)."""
    return (v[1], v[0], -v[2])
