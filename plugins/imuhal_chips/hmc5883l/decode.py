"""Pure decoding of HMC5883L data bytes (registers 0x03..0x08) into microtesla.

The six bytes are X, **Z**, Y (not X, Y, Z), each big-endian signed 16-bit. Valid values are
-2048..2047; -4096 marks an over/underflowed axis. Output is in the chip's sensor frame (the
axes printed on the package), in uT: counts / gain[LSB/gauss] * 100.
"""

from __future__ import annotations

from imuhal.core.samples import SampleFlag
from imuhal_chips.hmc5883l.registers import DATA_MAX, DATA_MIN, OVERFLOW_VALUE, UT_PER_GAUSS

Counts3 = tuple[int, int, int]
Vec3 = tuple[float, float, float]


def data_counts_xyz(data: bytes) -> Counts3:
    """Six data bytes in register order (X, Z, Y; big-endian) -> counts in X, Y, Z order."""
    if len(data) != 6:
        raise ValueError(f"HMC5883L data block is 6 bytes, got {len(data)}")
    x = int.from_bytes(data[0:2], "big", signed=True)
    z = int.from_bytes(data[2:4], "big", signed=True)
    y = int.from_bytes(data[4:6], "big", signed=True)
    return (x, y, z)


def counts_to_ut(counts: Counts3, gain_lsb_per_gauss: float) -> Vec3:
    """Counts (X, Y, Z) -> flux density in uT."""
    k = UT_PER_GAUSS / gain_lsb_per_gauss
    return (counts[0] * k, counts[1] * k, counts[2] * k)


def counts_flags(counts: Counts3) -> SampleFlag:
    """OVERFLOW if any axis holds the -4096 sentinel; OUT_OF_RANGE for any other value
    outside -2048..2047 (a corrupted read); OK otherwise."""
    flags = SampleFlag.OK
    for c in counts:
        if c == OVERFLOW_VALUE:
            flags |= SampleFlag.OVERFLOW
        elif not DATA_MIN <= c <= DATA_MAX:
            flags |= SampleFlag.OUT_OF_RANGE
    return flags


def encode_axis(field_gauss: float, gain_lsb_per_gauss: float) -> int:
    """What the chip stores for one axis (used by the emulator and tests): rounded counts,
    or -4096 when they do not fit -2048..2047."""
    counts = round(field_gauss * gain_lsb_per_gauss)
    return counts if DATA_MIN <= counts <= DATA_MAX else OVERFLOW_VALUE


def data_bytes_from_counts(counts_xyz: Counts3) -> bytes:
    """Counts (X, Y, Z) -> the six register bytes in chip order X, Z, Y (big-endian)."""
    x, y, z = counts_xyz
    return b"".join(v.to_bytes(2, "big", signed=True) for v in (x, z, y))
