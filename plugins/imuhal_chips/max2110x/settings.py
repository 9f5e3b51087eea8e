"""Settings of the MAX2110x drivers, in physical units, validated against the part's tables.

Defaults are the seed's configurations (nair 2016-09-20, "Sensor Configuration"):
MAX21100 paragliding: gyro +/-500 dps, 14 Hz bandwidth, 250 Hz ODR; accel +/-4 g,
LPF ODR/48, 250 Hz ODR. MAX21105 RC: gyro +/-1000 dps, 10 Hz, 200 Hz; accel +/-8 g, ODR/48,
200 Hz.
"""

from __future__ import annotations

from typing import Any, ClassVar

from pydantic import Field, field_validator

from imuhal.drivers.base import DriverSettings
from imuhal.drivers.settings import pick
from imuhal_chips.max2110x.registers import (
    ACCEL_LPF_DIVISOR,
    ACCEL_RANGE_G,
    GYRO_BANDWIDTH_HZ,
    GYRO_RANGE_DPS,
    MAX21100,
    MAX21105,
    PartSpec,
)


class Max2110xSettings(DriverSettings):
    """Common fields; each part's subclass sets ``part`` (its ODR tables) and defaults."""

    part: ClassVar[PartSpec] = MAX21100

    gyro_range_dps: int = 500
    """Gyro full scale, +/- deg/s: 250, 500, 1000, 2000."""
    gyro_bandwidth_hz: float = 14
    """Gyro low-pass bandwidth, Hz: 2, 4, 6, 8, 10, 14, 22, 32, 50, 75, 100, 150, 200, 250,
    300, 400."""
    gyro_odr_hz: float = 250
    """Gyro output data rate, Hz (part-specific table)."""
    accel_range_g: int = 4
    """Accelerometer full scale, +/- g: 2, 4, 8, 16."""
    accel_lpf: int = 48
    """Accelerometer low-pass cutoff as the ODR divisor (ODR/48, /22, /9, /3)."""
    accel_odr_hz: float = 250
    """Accelerometer output data rate, Hz (part-specific table)."""
    reset_check_s: float = Field(default=0.5, gt=0, le=60)
    """How often (s) the driver reads back its configuration to catch a silent chip reset."""

    @classmethod
    def choices(cls) -> dict[str, tuple[Any, ...]]:
        return {
            "gyro_range_dps": tuple(GYRO_RANGE_DPS),
            "gyro_bandwidth_hz": tuple(GYRO_BANDWIDTH_HZ),
            "gyro_odr_hz": tuple(cls.part.gyro_odr_hz),
            "accel_range_g": tuple(ACCEL_RANGE_G),
            "accel_lpf": tuple(ACCEL_LPF_DIVISOR),
            "accel_odr_hz": tuple(cls.part.accel_odr_hz),
        }

    @field_validator("gyro_range_dps", mode="before")
    @classmethod
    def _gyro_range(cls, v: float) -> int:
        return int(pick(GYRO_RANGE_DPS, v, "gyro_range_dps", "dps"))

    @field_validator("gyro_bandwidth_hz", mode="before")
    @classmethod
    def _gyro_bw(cls, v: float) -> float:
        return float(pick(GYRO_BANDWIDTH_HZ, v, "gyro_bandwidth_hz", "Hz"))

    @field_validator("gyro_odr_hz", mode="before")
    @classmethod
    def _gyro_odr(cls, v: float) -> float:
        return float(pick(cls.part.gyro_odr_hz, v, f"gyro_odr_hz ({cls.part.part})", "Hz"))

    @field_validator("accel_range_g", mode="before")
    @classmethod
    def _accel_range(cls, v: float) -> int:
        return int(pick(ACCEL_RANGE_G, v, "accel_range_g", "g"))

    @field_validator("accel_lpf", mode="before")
    @classmethod
    def _accel_lpf(cls, v: float) -> int:
        return int(pick(ACCEL_LPF_DIVISOR, v, "accel_lpf (ODR divisor)", ""))

    @field_validator("accel_odr_hz", mode="before")
    @classmethod
    def _accel_odr(cls, v: float) -> float:
        return float(pick(cls.part.accel_odr_hz, v, f"accel_odr_hz ({cls.part.part})", "Hz"))


class Max21100Settings(Max2110xSettings):
    """MAX21100 settings; defaults: the seed's paragliding configuration."""

    part: ClassVar[PartSpec] = MAX21100


class Max21105Settings(Max2110xSettings):
    """MAX21105 settings; defaults: the seed's RC configuration."""

    part: ClassVar[PartSpec] = MAX21105

    gyro_range_dps: int = 1000
    gyro_bandwidth_hz: float = 10
    gyro_odr_hz: float = 200
    accel_range_g: int = 8
    accel_lpf: int = 48
    accel_odr_hz: float = 200
