"""Stored calibration and how it is applied.

Inertial (accel, gyro): corrected = M @ diag(s) @ (raw - b), with b in the channel's SI unit.
Magnetic: corrected = S @ (raw - h), h in uT. Both act in the chip's sensor frame, before the
mount rotation (docs/units-and-frames.md). Each record is bound to the device it was measured
on; the pipeline refuses to apply a record whose binding does not match the probed chip.

Besides the three records a device's calibration may hold:

* ``previous``: the records each procedure replaced, one per channel, so a bad calibration can
  be undone by hand (``imuhal calibrate`` moves the old record here before writing);
* ``gyro_at_startup``: measure the gyro offsets again at every start-up, with the board kept
  still (see :mod:`imuhal.pipeline.startup`), overriding the stored offsets only;
* ``mag_in_flight``: learn the magnetometer's hard iron from turns while no magnetometer
  record is stored (see :mod:`imuhal.calibration.hard_iron`);
* ``accel_in_flight``: learn the accelerometer's offset from GNSS velocity and the
  barometer while no accelerometer record is stored (see
  :mod:`imuhal.calibration.accel_in_flight`).
"""

from __future__ import annotations

from datetime import datetime, timezone
from typing import Annotated, Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, ValidationInfo, field_validator

Finite = Annotated[float, Field(allow_inf_nan=False)]
"""A finite float: NaN or inf in a stored calibration would poison every sample it touches."""
Positive = Annotated[float, Field(gt=0, allow_inf_nan=False)]
Vec3 = tuple[Finite, Finite, Finite]
Scale3 = tuple[Positive, Positive, Positive]
"""Per-axis scale factors: finite and > 0 (0 would erase an axis, a sign flip is a mount)."""
Mat3 = tuple[Vec3, Vec3, Vec3]
IDENTITY3: Mat3 = ((1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0))
ChannelName = Literal["accel", "gyro", "mag"]
CHANNELS: tuple[ChannelName, ...] = ("accel", "gyro", "mag")


def now() -> datetime:
    """The date stored with a record measured now: UTC, whole seconds."""
    return datetime.now(timezone.utc).replace(microsecond=0)


class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


class CalibrationBinding(_Strict):
    """The device a calibration was measured on.

    ``bus`` is the profile's bus reference (``spi0``, ``imu/aux``), ``identity`` the probe's
    evidence (``WHO_AM_I=0x11``) and ``calibration_version`` the driver's: a driver bumps it
    when a change to its decoding would make old calibrations wrong.
    """

    driver: str
    bus: str
    address: int
    identity: str
    calibration_version: int = 1


class _Record(_Strict):
    binding: CalibrationBinding | None = None
    procedure: str = "manual"
    """How the record was measured (``gyro-at-rest``, ``accel-six-position``,
    ``accel-six-position-lsq``, ``mag-ellipsoid``, ``mag-minmax``, or ``manual``)."""
    date: datetime | None = None
    quality: dict[str, float] = Field(default_factory=dict)
    """Figures of merit of the measurement; names carry units (``residual_rms_mg``)."""


def _check_matrix(m: Mat3) -> Mat3:
    a = np.asarray(m, dtype=float)
    if not np.all(np.isfinite(a)):
        raise ValueError("matrix entries must be finite")
    if abs(float(np.linalg.det(a))) < 1e-6:
        raise ValueError("matrix is singular: it would collapse an axis")
    return m


class AccelCalibration(_Record):
    """Accelerometer: offset in m/s^2 (raw units), per-axis scale, unit-diagonal
    misalignment; ``apply`` maps a raw sensor-frame reading to a corrected one."""

    offset_m_s2: Vec3 = (0.0, 0.0, 0.0)
    scale: Annotated[Scale3, Field(description="multiplier per axis (1/sensitivity error)")] = (
        1.0, 1.0, 1.0)
    misalignment: Mat3 = IDENTITY3

    _m = field_validator("misalignment")(_check_matrix)

    def apply(self, raw: Vec3) -> Vec3:
        return _inertial(raw, self.offset_m_s2, self.scale, self.misalignment)


class GyroCalibration(_Record):
    """Gyroscope: offset in rad/s, per-axis scale, unit-diagonal misalignment."""

    offset_rad_s: Vec3 = (0.0, 0.0, 0.0)
    scale: Scale3 = (1.0, 1.0, 1.0)
    misalignment: Mat3 = IDENTITY3

    _m = field_validator("misalignment")(_check_matrix)

    def apply(self, raw: Vec3) -> Vec3:
        return _inertial(raw, self.offset_rad_s, self.scale, self.misalignment)


class MagCalibration(_Record):
    """Magnetometer: hard iron h in uT and soft-iron matrix S (symmetric when fitted)."""

    hard_iron_ut: Vec3 = (0.0, 0.0, 0.0)
    soft_iron: Mat3 = IDENTITY3

    _m = field_validator("soft_iron")(_check_matrix)

    def apply(self, raw: Vec3) -> Vec3:
        h = self.hard_iron_ut
        return _mat_vec(self.soft_iron, (raw[0] - h[0], raw[1] - h[1], raw[2] - h[2]))


class GyroStartupSettings(_Strict):
    """Re-measure gyro offsets at every start-up (the seed: "ideally ... each time on power
    up"). The board must be kept still for ``samples`` gyro samples; when it moves or an axis
    reads more than ``max_offset_dps`` the measurement waits ``retry_wait_s`` and repeats, at
    most ``max_attempts`` times, after which the stored offsets are kept.

    ``max_attempts`` is 1 by default: a board that moves at switch-on may be flying (a
    brown-out reboot in the air), and every retry withheld every estimate (five attempts
    2 s apart: 10.5 s); the AHRS checks a start it was not told was still
    (``start_check_s``, docs/estimators.md). Give more attempts to wait for a board set down
    on the ground."""

    enabled: bool = True
    samples: int = Field(100, ge=10, le=100_000)
    max_offset_dps: float = Field(10.0, gt=0)
    max_gyro_std_dps: float = Field(0.5, gt=0)
    max_accel_std_m_s2: float = Field(0.1, gt=0)
    retry_wait_s: float = Field(2.0, ge=0)
    max_attempts: int = Field(1, ge=1)


class VectorCalibration(_Record):
    """Any other vector quantity (one a plugin adds): corrected = matrix @ (raw - offset),
    ``offset`` in the quantity's own unit, in the sensor frame. Stored under the quantity's
    name (``calibration: {airflow: {offset: [...]}}``)."""

    offset: Vec3 = (0.0, 0.0, 0.0)
    matrix: Mat3 = IDENTITY3

    _m = field_validator("matrix")(_check_matrix)

    def apply(self, raw: Vec3) -> Vec3:
        o = self.offset
        return _mat_vec(self.matrix, (raw[0] - o[0], raw[1] - o[1], raw[2] - o[2]))


class _Records(BaseModel):
    """accel, gyro and mag records by name, and any other vector quantity's
    :class:`VectorCalibration` under its quantity name (extra keys)."""

    model_config = ConfigDict(extra="allow", frozen=True)
    __pydantic_extra__: dict[str, VectorCalibration] = Field(init=False)

    accel: AccelCalibration | None = None
    gyro: GyroCalibration | None = None
    mag: MagCalibration | None = None

    def records(self) -> dict[str, Record]:
        """Every record held, by quantity name (accel, gyro, mag first)."""
        out: dict[str, Record] = {c: r for c in CHANNELS if (r := getattr(self, c)) is not None}
        out.update({k: v for k, v in (self.model_extra or {}).items() if v is not None})
        return out

    def record_for(self, quantity: str) -> Record | None:
        """The record of ``quantity`` (a quantity name), or None."""
        if quantity in CHANNELS:
            return getattr(self, quantity)
        extra = self.model_extra
        return extra.get(quantity) if extra else None


class PreviousCalibration(_Records):
    """The records the last run of each procedure replaced (a backup, never applied)."""


Record = AccelCalibration | GyroCalibration | MagCalibration | VectorCalibration


class MagInFlightSettings(_Strict):
    """Learn the magnetometer's hard iron in flight, from the field's rotation in turns, while
    the device has no stored magnetometer record (imuhal.calibration.hard_iron). The learned
    offset is applied (in memory) once its standard deviation is below ``max_std_ut`` on
    every axis after at least ``min_readings`` readings, each ``min_step_ut`` away from the
    previous one taken (readings of a board at rest add no information)."""

    enabled: bool = True
    min_readings: int = Field(100, ge=10)
    min_step_ut: float = Field(2.0, gt=0)
    max_std_ut: float = Field(0.5, gt=0)
    noise_floor_ut: float = Field(0.15, gt=0)
    """The least noise a reading is assumed to carry (about one LSB): the fit's uncertainty
    is never computed from a smaller residual, so readings that fit too well (a circle of a
    steady turn lies exactly on many spheres) do not look certain."""


class AccelInFlightSettings(_Strict):
    """Learn the accelerometer's offset in flight while the device has no stored
    accelerometer record (imuhal.calibration.accel_in_flight): from the GNSS velocity during
    manoeuvres (every axis) and the barometer (the axis that points down). A body axis is
    applied (in memory) once its offset's standard deviation is at most ``max_std_mg`` after
    at least ``min_updates`` measurements. The noise figures are the filter's model of the
    sensors; the defaults are those of a consumer MEMS IMU (MPU-9250 class), an MS5611-class
    barometer and a u-blox receiver."""

    enabled: bool = True
    min_updates: int = Field(50, ge=10)
    max_std_mg: float = Field(3.0, gt=0)
    """3 mg: a tilt of 0.17 deg."""
    initial_offset_mg: float | None = Field(None, gt=0)
    """The offset's standard deviation before flight, per axis; None: the chip's specified
    offset (its driver's ``specified_offset``), else 60 mg."""
    initial_tilt_deg: float = Field(2.0, gt=0)
    """How far the AHRS's attitude the learner starts from may be off, besides the tilt the
    offset causes."""
    initial_heading_deg: float = Field(20.0, gt=0)
    gnss_velocity_noise_m_s: float = Field(0.05, gt=0)
    """The least noise a GNSS velocity is assumed to carry per axis (its receiver's speed
    accuracy is used when larger)."""
    baro_noise_m: float = Field(0.3, gt=0)
    """Noise of the barometer's altitude, turbulence in the air included."""
    baro_interval_s: float = Field(0.2, gt=0)
    """The barometer is fused at most this often."""
    initial_lag_s: float = Field(0.2, gt=0)
    """How late the GNSS velocity's stamps may be before flight (s): the receiver's output
    latency and the line's transfer time the driver does not know of."""
    attitude_random_walk_rad_sqrt_s: float = Field(0.002, gt=0)
    """The gyro's angle random walk and its residual offset's drift (rad/sqrt(s))."""
    gyro_scale_error: float = Field(0.03, ge=0)
    """The gyro's sensitivity error (3 %: the MPU-9250's tolerance): the attitude's
    uncertainty grows by it times the angle turned."""
    velocity_random_walk_m_s_sqrt_s: float = Field(0.01, gt=0)
    """The accelerometer's noise integrated into velocity (m/s/sqrt(s))."""
    offset_random_walk_mg_sqrt_s: float = Field(0.01, ge=0)
    """How fast the offset itself may wander (temperature), mg/sqrt(s)."""


_SWITCHES = {"on": True, "off": False, "true": True, "false": False}


def _in_flight_switch(value: object, info: ValidationInfo) -> object:
    """``true``/``on`` (the learner's default settings), ``false``/``off`` (never learn,
    not even by default) or the settings themselves; anything else is one error naming the
    accepted forms."""
    if isinstance(value, str) and value.strip().lower() in _SWITCHES:
        value = _SWITCHES[value.strip().lower()]
    if isinstance(value, bool):
        return {"enabled": value}
    if value is None or isinstance(value, dict | BaseModel):
        return value
    raise ValueError(
        f"must be on, off or a mapping of the learner's settings, e.g. `{info.field_name}: "
        f"off` to never learn in flight or `{info.field_name}: {{max_std_mg: 3}}` "
        "(docs/calibration.md, \"Learning in flight by default\")")


class DeviceCalibration(_Records):
    gyro_at_startup: GyroStartupSettings | None = None
    mag_in_flight: MagInFlightSettings | None = None
    """None: not set, so the magnetometer learns its hard iron in flight by default when no
    record is stored and none is measured before the run (imuhal.pipeline.learning
    ``learned_by_default``); ``off`` (``enabled: false``): never."""
    accel_in_flight: AccelInFlightSettings | None = None
    """None: not set, so the accelerometer learns its offset in flight by default when no
    record is stored, none is measured before the run and the board has a GNSS velocity;
    ``off`` (``enabled: false``): never."""
    previous: PreviousCalibration | None = None

    _switch = field_validator("mag_in_flight", "accel_in_flight", mode="before")(
        _in_flight_switch)

    def replaced(self, channel: str, record: Record) -> DeviceCalibration:
        """A copy with ``channel`` (a quantity name) set to ``record``; the record it replaces
        (if any) is kept in ``previous``."""
        old = self.record_for(channel)
        previous = self.previous or PreviousCalibration()
        if old is not None:
            previous = PreviousCalibration.model_validate(
                {**previous.records(), channel: old})
        data = {**self.records(), channel: record,
                "gyro_at_startup": self.gyro_at_startup, "mag_in_flight": self.mag_in_flight,
                "accel_in_flight": self.accel_in_flight,
                "previous": previous if previous.records() else None}
        return DeviceCalibration.model_validate(data)


def _inertial(raw: Vec3, offset: Vec3, scale: Vec3, m: Mat3) -> Vec3:
    return _mat_vec(m, ((raw[0] - offset[0]) * scale[0], (raw[1] - offset[1]) * scale[1],
                        (raw[2] - offset[2]) * scale[2]))


def _mat_vec(m: Mat3, v: Vec3) -> Vec3:
    # Plain floats: this runs for every calibrated sample, where numpy's per-call overhead
    # on 3-vectors costs more than the arithmetic.
    return (m[0][0] * v[0] + m[0][1] * v[1] + m[0][2] * v[2],
            m[1][0] * v[0] + m[1][1] * v[1] + m[1][2] * v[2],
            m[2][0] * v[0] + m[2][1] * v[1] + m[2][2] * v[2])
