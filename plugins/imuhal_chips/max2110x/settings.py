"""Settings of the MAX2110x drivers, in physical units, validated against the part's tables.

Defaults are the seed's configurations (nair 2016-09-20, "Sensor Configuration"):
MAX21100 paragliding: gyro +/-500 dps, 14 Hz bandwidth, 250 Hz ODR; accel +/-4 g,
LPF ODR/48, 250 Hz ODR. MAX21105 RC: gyro +/-1000 dps, 10 Hz, 200 Hz; accel +/-8 g, ODR/48,
200 Hz.
"""

from __future__ import annotations

from typing import Any, ClassVar, Literal

from pydantic import Field, model_validator

from imuhal.drivers.base import DriverSettings
from imuhal.drivers.polling import reset_check_field
from imuhal.drivers.settings import table_setting
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
    """Common fields; each part's subclass sets ``part`` and its own ODR tables and defaults."""

    part: ClassVar[PartSpec] = MAX21100
    renamed: ClassVar[dict[str, str]] = {
        "gyro_bandwidth_hz": "gyro_lpf_hz", "accel_lpf": "accel_lpf_divisor"}

    gyro_range_dps: table_setting(GYRO_RANGE_DPS, "dps", kind=int) = 500  # type: ignore[valid-type]  # an Annotated type a function builds (allowed values): pydantic reads it, mypy cannot
    """Gyro full scale, +/- deg/s: 250, 500, 1000, 2000."""
    gyro_lpf_hz: table_setting(GYRO_BANDWIDTH_HZ, "Hz") = 14  # type: ignore[valid-type]  # an Annotated type a function builds (allowed values): pydantic reads it, mypy cannot
    """Gyro low-pass bandwidth, Hz: 2, 4, 6, 8, 10, 14, 22, 32, 50, 75, 100, 150, 200, 250,
    300, 400."""
    gyro_odr_hz: float = 250
    """Gyro output data rate, Hz (part-specific table, set by each part's subclass)."""
    accel_range_g: table_setting(ACCEL_RANGE_G, "g", kind=int) = 4  # type: ignore[valid-type]  # an Annotated type a function builds (allowed values): pydantic reads it, mypy cannot
    """Accelerometer full scale, +/- g: 2, 4, 8, 16."""
    accel_lpf_divisor: table_setting(ACCEL_LPF_DIVISOR, "",  # type: ignore[valid-type]  # an Annotated type a function builds (allowed values): pydantic reads it, mypy cannot
                                     kind=int, label="accel_lpf_divisor (ODR divisor)") = 48
    """Accelerometer low-pass cutoff as the ODR divisor (ODR/48, /22, /9, /3)."""
    accel_odr_hz: float = 250
    """Accelerometer output data rate, Hz (part-specific table, set by each part's subclass)."""
    reset_check_s: float = reset_check_field()
    """How often (s) the driver reads back its configuration to catch a silent chip reset."""
    read: Literal["registers", "fifo"] = "registers"
    """``registers``: the data registers (one sample) polled on a grid after each
    measurement; ``fifo``: the chip keeps gyro + accel frames in its FIFO (10 frames, 40 ms
    at 250 Hz; what of each part's FIFO is assumed: imuhal_chips.max2110x.fifo) and
    the driver reads them in bursts every ``fifo_frames`` periods, stamped on the chip's
    own clock, so a host stall of up to 80 % of the FIFO loses nothing."""
    fifo_frames: int = Field(default=1, ge=1, le=8)
    """read: fifo: read the FIFO every this many periods. A host stall of up to 10 -
    fifo_frames - 1 periods (the read's phase) loses nothing: 32 ms at 250 Hz with 1."""

    @model_validator(mode="after")
    def _fifo_readable(self) -> Max2110xSettings:
        if self.read != "fifo":
            return self
        if float(self.gyro_odr_hz) != float(self.accel_odr_hz):
            raise ValueError(
                f"read: fifo needs gyro_odr_hz equal to accel_odr_hz (the FIFO writes both "
                f"in one frame), got {self.gyro_odr_hz:g} and {self.accel_odr_hz:g}; set "
                "both to the same rate or use read: registers")
        return self


def _odr(part: PartSpec, which: str) -> Any:
    table = getattr(part, f"{which}_odr_hz")
    return table_setting(table, "Hz", label=f"{which}_odr_hz ({part.part})")


class Max21100Settings(Max2110xSettings):
    """MAX21100 settings; defaults: the seed's paragliding configuration."""

    part: ClassVar[PartSpec] = MAX21100

    gyro_odr_hz: _odr(MAX21100, "gyro") = 250  # type: ignore[valid-type]  # an Annotated type a function builds (allowed values): pydantic reads it, mypy cannot
    accel_odr_hz: _odr(MAX21100, "accel") = 250  # type: ignore[valid-type]  # an Annotated type a function builds (allowed values): pydantic reads it, mypy cannot


class Max21105Settings(Max2110xSettings):
    """MAX21105 settings; defaults: the seed's RC configuration."""

    part: ClassVar[PartSpec] = MAX21105

    gyro_range_dps: table_setting(GYRO_RANGE_DPS, "dps", kind=int) = 1000  # type: ignore[valid-type]  # an Annotated type a function builds (allowed values): pydantic reads it, mypy cannot
    gyro_lpf_hz: table_setting(GYRO_BANDWIDTH_HZ, "Hz") = 10  # type: ignore[valid-type]  # an Annotated type a function builds (allowed values): pydantic reads it, mypy cannot
    gyro_odr_hz: _odr(MAX21105, "gyro") = 200  # type: ignore[valid-type]  # an Annotated type a function builds (allowed values): pydantic reads it, mypy cannot
    accel_range_g: table_setting(ACCEL_RANGE_G, "g", kind=int) = 8  # type: ignore[valid-type]  # an Annotated type a function builds (allowed values): pydantic reads it, mypy cannot
    accel_odr_hz: _odr(MAX21105, "accel") = 200  # type: ignore[valid-type]  # an Annotated type a function builds (allowed values): pydantic reads it, mypy cannot
