"""Timestamped samples. Units are in the field names; frames are in the ``frame`` field.

Every sample carries ``t_ns`` (int nanoseconds on the pipeline clock), the name of the device
that produced it, the frame its vector is expressed in, and quality flags. A sample whose
``flags`` are not ``SampleFlag.OK`` is never fused: the pipeline counts it and passes it to
sinks marked invalid.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace
from enum import Enum, IntEnum, IntFlag
from typing import Any, ClassVar, TypeAlias

from typing_extensions import Self  # typing.Self is Python 3.11+

from imuhal.core.quantities import Quantity as Quantity  # re-exported: a sample names its quantity

Vec3: TypeAlias = tuple[float, float, float]


class Frame(str, Enum):
    """Which axes a vector sample is expressed in."""

    SENSOR = "sensor"
    """The chip's own axes, as printed in its datasheet."""
    BODY_NED = "body_ned"
    """The board/vehicle body frame: x forward, y right, z down."""


class SampleFlag(IntFlag):
    """Why a sample must not be fused. OK (0) means it may be."""

    OK = 0
    NAN = 1 << 0
    """A value is NaN or infinite."""
    OVERFLOW = 1 << 1
    """The chip reported overflow (e.g. HMC5883L -4096, AK8963 HOFL)."""
    SATURATED = 1 << 2
    """A value sits at the configured full scale: the true value may be larger."""
    CRC_ERROR = 1 << 3
    """An integrity check failed."""
    BUS_ERROR = 1 << 4
    """The transfer that should have carried the sample failed."""
    STALE = 1 << 5
    """The chip had no new data (data-ready not set when it should have been)."""
    OUT_OF_RANGE = 1 << 6
    """The value is outside what the chip can physically report (datasheet limits, or
    beyond the configured full scale)."""
    OUT_OF_ORDER = 1 << 7
    """The sample is older than one its device already delivered for the same quantity."""
    BLANK = 1 << 8
    """The frame read all 0x00 or all 0xFF: nothing drove the bus (chip absent or
    unpowered, a slave missing behind an I2C master, a data line stuck)."""
    FROZEN = 1 << 9
    """The chip repeated the same raw frame for longer than its noise allows: its
    conversions hung (a real sensor's noise never repeats one raw word for long)."""
    FILTER_SETTLING = 1 << 10
    """The chip's own filter (IIR, digital low-pass, averaging) may still carry an earlier
    measurement that was flagged wrong (saturated, out of range, overflow): the value can be
    in range and still off by far more than the noise."""
    IMPLAUSIBLE = 1 << 11
    """The value moved further from the last valid one than the measured quantity can move
    in the time between them (a pressure step no vertical speed makes): the chip's element
    or converter was disturbed while it measured. Also a value with nothing valid yet to be
    held against that the readings after it have not confirmed (a GNSS receiver's first
    fixes)."""
    CONTRADICTED = 1 << 12
    """Another sensor on the board measured the same quantity and contradicts the value
    beyond what both sensors' errors allow (a GNSS height or vertical velocity against the
    barometer: imuhal.pipeline.crosscheck)."""


@dataclass(frozen=True, slots=True, kw_only=True)
class Sample:
    """Base of all samples. Subclasses add one value field whose name carries the unit."""

    t_ns: int
    device: str
    flags: SampleFlag = SampleFlag.OK
    channel: ClassVar[Quantity]
    """The quantity measured (a plugin's sample class names its own)."""

    @property
    def valid(self) -> bool:
        return not self.flags  # SampleFlag.OK is 0 (asked for every sample, several times)

    def flagged(self, flag: SampleFlag) -> Sample:
        """A copy with ``flag`` added."""
        return replace(self, flags=self.flags | flag)


@dataclass(frozen=True, slots=True, kw_only=True)
class VectorSample(Sample):
    """A three-axis sample; ``vector`` is the value in the unit of ``channel``."""

    frame: Frame = Frame.SENSOR

    @property
    def vector(self) -> Vec3:
        raise NotImplementedError

    def with_vector(self, vector: Vec3, frame: Frame) -> VectorSample:
        raise NotImplementedError

    _set_vector: ClassVar[Callable[[VectorSample, Vec3], None]]
    """The value field's slot setter (assigned below the built-in classes)."""

    @classmethod
    def build(cls, t_ns: int, device: str, flags: SampleFlag, frame: Frame,
              vector: Vec3) -> Self:
        """The same sample as the keyword constructor, built faster (every sample comes
        through here): the fields are set through their slots, where the generated
        ``__init__`` of a frozen class goes through ``object.__setattr__`` per field.
        ``vector`` (the class's value field) must already be a tuple of three floats.
        For the built-in vector samples; a plugin's class sets ``_set_vector`` to use it."""
        s = _new(cls)
        _set_t_ns(s, t_ns)
        _set_device(s, device)
        _set_flags(s, flags)
        _set_frame(s, frame)
        cls._set_vector(s, vector)
        return s


@dataclass(frozen=True, slots=True, kw_only=True)
class ScalarSample(Sample):
    @property
    def scalar(self) -> float:
        raise NotImplementedError


@dataclass(frozen=True, slots=True, kw_only=True)
class AccelSample(VectorSample):
    """Specific force in m/s^2 (not gravity-positive: level at rest is (0, 0, -9.81) NED)."""

    accel_m_s2: Vec3 = field(default=(0.0, 0.0, 0.0))
    channel: ClassVar[Quantity] = Quantity.ACCEL

    @property
    def vector(self) -> Vec3:
        return self.accel_m_s2

    def with_vector(self, vector: Vec3, frame: Frame) -> AccelSample:
        return AccelSample.build(self.t_ns, self.device, self.flags, frame, _vec3(vector))



@dataclass(frozen=True, slots=True, kw_only=True)
class GyroSample(VectorSample):
    """Angular rate in rad/s."""

    gyro_rad_s: Vec3 = field(default=(0.0, 0.0, 0.0))
    channel: ClassVar[Quantity] = Quantity.GYRO

    @property
    def vector(self) -> Vec3:
        return self.gyro_rad_s

    def with_vector(self, vector: Vec3, frame: Frame) -> GyroSample:
        return GyroSample.build(self.t_ns, self.device, self.flags, frame, _vec3(vector))



@dataclass(frozen=True, slots=True, kw_only=True)
class MagSample(VectorSample):
    """Magnetic flux density in uT."""

    mag_ut: Vec3 = field(default=(0.0, 0.0, 0.0))
    channel: ClassVar[Quantity] = Quantity.MAG

    @property
    def vector(self) -> Vec3:
        return self.mag_ut

    def with_vector(self, vector: Vec3, frame: Frame) -> MagSample:
        return MagSample.build(self.t_ns, self.device, self.flags, frame, _vec3(vector))



@dataclass(frozen=True, slots=True, kw_only=True)
class PressureSample(ScalarSample):
    """Static pressure in Pa."""

    pressure_pa: float = 0.0
    channel: ClassVar[Quantity] = Quantity.PRESSURE

    @property
    def scalar(self) -> float:
        return self.pressure_pa


@dataclass(frozen=True, slots=True, kw_only=True)
class TemperatureSample(ScalarSample):
    """Die temperature in degC."""

    temperature_degc: float = 0.0
    channel: ClassVar[Quantity] = Quantity.TEMPERATURE

    @property
    def scalar(self) -> float:
        return self.temperature_degc


@dataclass(frozen=True, slots=True, kw_only=True)
class VelocitySample(Sample):
    """Velocity over ground in the earth NED frame (m/s), as a GNSS receiver reports it.

    Not a body-frame vector: no mount rotation applies. ``t_ns`` is the time the velocity was
    *valid* (the receiver's measurement epoch on the pipeline clock), not when it arrived, so
    a consumer can account for the receiver's latency. ``accuracy_m_s`` is the 1-sigma speed
    accuracy the source claims (None: unknown).
    """

    velocity_ned_m_s: Vec3 = field(default=(0.0, 0.0, 0.0))
    accuracy_m_s: float | None = None
    channel: ClassVar[Quantity] = Quantity.VELOCITY


@dataclass(frozen=True, slots=True, kw_only=True)
class AirspeedSample(ScalarSample):
    """True airspeed along the body x axis (m/s, forward +), e.g. from a pitot tube."""

    airspeed_m_s: float = 0.0
    accuracy_m_s: float | None = None
    channel: ClassVar[Quantity] = Quantity.AIRSPEED

    @property
    def scalar(self) -> float:
        return self.airspeed_m_s


class FixType(IntEnum):
    """What a GNSS receiver says its position solution is (the u-blox NAV-PVT ``fixType``
    codes; NMEA GGA quality and GSA mode map onto them)."""

    NO_FIX = 0
    DEAD_RECKONING = 1
    FIX_2D = 2
    FIX_3D = 3
    GNSS_DEAD_RECKONING = 4
    TIME_ONLY = 5


class HeightDatum(str, Enum):
    """What a GNSS height is measured from."""

    MSL = "msl"
    """Mean sea level (the geoid: NMEA GGA altitude, NAV-PVT hMSL)."""
    ELLIPSOID = "ellipsoid"
    """The WGS-84 ellipsoid (NAV-PVT height; GGA altitude + geoid separation)."""


@dataclass(frozen=True, slots=True, kw_only=True)
class PositionSample(Sample):
    """A geodetic position fix, as a GNSS receiver reports it.

    ``latitude_deg``/``longitude_deg`` are WGS-84 degrees (north/east positive);
    ``height_m`` is measured from ``height_datum``. Accuracies are the receiver's 1-sigma
    estimates (m; None: not reported). Like :class:`VelocitySample` it is an earth-frame
    quantity (no mount rotation) and ``t_ns`` is the measurement epoch on the pipeline clock.
    A sample without a fix is flagged (``SampleFlag.STALE``), never fused.
    """

    latitude_deg: float = 0.0
    longitude_deg: float = 0.0
    height_m: float = 0.0
    height_datum: HeightDatum = HeightDatum.MSL
    horizontal_accuracy_m: float | None = None
    vertical_accuracy_m: float | None = None
    fix_type: FixType = FixType.NO_FIX
    satellites: int = 0
    utc_s: float | None = None
    """The epoch in UTC as the receiver stamped it (s since 1970-01-01; None: unknown)."""
    channel: ClassVar[Quantity] = Quantity.POSITION


def slot_setter(cls: type, name: str) -> Callable[[Any, Any], None]:
    """The setter of the slot ``name`` that ``cls`` declares: it writes past a frozen
    dataclass's ``__setattr__`` (the ``build`` fast paths set every field through these)."""
    setter: Callable[[Any, Any], None] = vars(cls)[name].__set__
    return setter


# Slot setters for the ``build`` fast paths (a frozen class forbids plain assignment).
_new = object.__new__
_set_t_ns = slot_setter(Sample, "t_ns")
_set_device = slot_setter(Sample, "device")
_set_flags = slot_setter(Sample, "flags")
_set_frame = slot_setter(VectorSample, "frame")
AccelSample._set_vector = slot_setter(AccelSample, "accel_m_s2")
GyroSample._set_vector = slot_setter(GyroSample, "gyro_rad_s")
MagSample._set_vector = slot_setter(MagSample, "mag_ut")


SAMPLE_TYPES: dict[Quantity, type[Sample]] = {
    Quantity.ACCEL: AccelSample,
    Quantity.GYRO: GyroSample,
    Quantity.MAG: MagSample,
    Quantity.PRESSURE: PressureSample,
    Quantity.TEMPERATURE: TemperatureSample,
    Quantity.VELOCITY: VelocitySample,
    Quantity.AIRSPEED: AirspeedSample,
    Quantity.POSITION: PositionSample,
}
"""imuhal's own quantities and their sample classes (always in ``Registry.quantities``;
plugins add theirs through ``imuhal_register_quantities``)."""


def _vec3(v: Sequence[float]) -> Vec3:
    return (float(v[0]), float(v[1]), float(v[2]))
