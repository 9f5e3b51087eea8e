"""imuhal events as ROS 2 messages (REP-103 frames, REP-145 topics), without ROS installed.

:class:`RosMessages` turns the pipeline's events into ``(topic, type, message)`` records whose
messages are plain dicts with the fields of the ROS 2 interface (any CDR encoder that takes
mappings writes them). The conversion happens here, at the edge, with
:mod:`imuhal.core.conventions` exactly as ``--output-frame enu`` does:

* body vectors FRD -> FLU (``enu`` convention, specific force: level at rest reads
  linear_acceleration z = +9.81 m/s^2), orientation body -> NED as FLU -> ENU (a level board
  facing north has yaw +90 deg about up), GNSS velocity NED -> ENU;
* units: magnetic field uT -> T, pressure Pa, temperature degC, angles rad;
* ``header.stamp`` is the event's own time (``t_ns`` on the pipeline clock: the measurement
  epoch for GNSS samples), ``header.frame_id`` the board's frame.

Topics (REP-145 for the IMU): ``imu/data_raw`` (accelerometer and gyro samples; no
orientation: ``orientation_covariance[0] = -1``), ``imu/data`` (the attitude estimate, with
the latest raw rates and specific force), ``imu/mag``, ``pressure``, ``gps/fix``, ``gps/vel``
and ``DEVICE/temperature``. ``gps/vel`` is a TwistWithCovarianceStamped whose linear part is
the GNSS velocity in ENU (east, north, up; the earth frame, as nmea_navsat_driver publishes
it) and whose angular part is zero (not measured). The first device (or estimator) of each
kind takes the plain topic; any other is put under its own name (``baro2/pressure``,
``vqf/imu/data``).

Flagged samples are not converted (a ROS message has no validity flag, so a flagged value
would be taken as good); nor are sensor-frame vectors (no body axes). Both are counted in
``skipped``. Vertical estimates have no ROS 2 message type and are not written.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from dataclasses import dataclass, field
from typing import Any

from imuhal.core.conventions import ENU, NED, convert_earth_vector, convert_quat
from imuhal.core.samples import (
    AccelSample,
    FixType,
    Frame,
    GyroSample,
    HeightDatum,
    MagSample,
    PositionSample,
    PressureSample,
    Sample,
    TemperatureSample,
    VectorSample,
    VelocitySample,
)
from imuhal.estimation.framed import express_sample
from imuhal.estimation.outputs import AttitudeEstimate
from imuhal.sinks.base import Event
from imuhal.sinks.ros.settings import RosSettings

# ---------------------------------------------------------------------------------------------
# Interface definitions (ROS 2 .msg text, the fields of the Humble/Jazzy interfaces), in the
# concatenated form MCAP's ros2msg schema encoding uses: the type, then each type it uses.

_TIME = "int32 sec\nuint32 nanosec\n"
_HEADER = "builtin_interfaces/Time stamp\nstring frame_id\n"
_QUATERNION = "float64 x 0\nfloat64 y 0\nfloat64 z 0\nfloat64 w 1\n"
_VECTOR3 = "float64 x\nfloat64 y\nfloat64 z\n"
_IMU = ("std_msgs/Header header\n"
        "geometry_msgs/Quaternion orientation\nfloat64[9] orientation_covariance\n"
        "geometry_msgs/Vector3 angular_velocity\nfloat64[9] angular_velocity_covariance\n"
        "geometry_msgs/Vector3 linear_acceleration\nfloat64[9] linear_acceleration_covariance\n")
_MAGNETIC_FIELD = ("std_msgs/Header header\ngeometry_msgs/Vector3 magnetic_field\n"
                   "float64[9] magnetic_field_covariance\n")
_FLUID_PRESSURE = "std_msgs/Header header\nfloat64 fluid_pressure\nfloat64 variance\n"
_TEMPERATURE = "std_msgs/Header header\nfloat64 temperature\nfloat64 variance\n"
_NAV_SAT_STATUS = ("int8 STATUS_NO_FIX=-1\nint8 STATUS_FIX=0\nint8 STATUS_SBAS_FIX=1\n"
                   "int8 STATUS_GBAS_FIX=2\nint8 status\n"
                   "uint16 SERVICE_GPS=1\nuint16 SERVICE_GLONASS=2\nuint16 SERVICE_COMPASS=4\n"
                   "uint16 SERVICE_GALILEO=8\nuint16 service\n")
_NAV_SAT_FIX = ("std_msgs/Header header\nsensor_msgs/NavSatStatus status\n"
                "float64 latitude\nfloat64 longitude\nfloat64 altitude\n"
                "float64[9] position_covariance\n"
                "uint8 COVARIANCE_TYPE_UNKNOWN=0\nuint8 COVARIANCE_TYPE_APPROXIMATED=1\n"
                "uint8 COVARIANCE_TYPE_DIAGONAL_KNOWN=2\nuint8 COVARIANCE_TYPE_KNOWN=3\n"
                "uint8 position_covariance_type\n")
_TWIST = "geometry_msgs/Vector3 linear\ngeometry_msgs/Vector3 angular\n"
_TWIST_WITH_COVARIANCE = "geometry_msgs/Twist twist\nfloat64[36] covariance\n"
_TWIST_WITH_COVARIANCE_STAMPED = ("std_msgs/Header header\n"
                                  "geometry_msgs/TwistWithCovariance twist\n")


def _msgdef(main: str, *deps: tuple[str, str]) -> str:
    parts = [main]
    for name, text in deps:
        parts.append("=" * 80 + f"\nMSG: {name}\n{text}")
    return "\n".join(parts)


_HEADER_DEPS = (("std_msgs/Header", _HEADER), ("builtin_interfaces/Time", _TIME))

IMU = "sensor_msgs/msg/Imu"
MAGNETIC_FIELD = "sensor_msgs/msg/MagneticField"
FLUID_PRESSURE = "sensor_msgs/msg/FluidPressure"
TEMPERATURE = "sensor_msgs/msg/Temperature"
NAV_SAT_FIX = "sensor_msgs/msg/NavSatFix"
TWIST_WITH_COVARIANCE_STAMPED = "geometry_msgs/msg/TwistWithCovarianceStamped"

MSGDEFS: dict[str, str] = {
    IMU: _msgdef(_IMU, *_HEADER_DEPS, ("geometry_msgs/Quaternion", _QUATERNION),
                 ("geometry_msgs/Vector3", _VECTOR3)),
    MAGNETIC_FIELD: _msgdef(_MAGNETIC_FIELD, *_HEADER_DEPS,
                            ("geometry_msgs/Vector3", _VECTOR3)),
    FLUID_PRESSURE: _msgdef(_FLUID_PRESSURE, *_HEADER_DEPS),
    TEMPERATURE: _msgdef(_TEMPERATURE, *_HEADER_DEPS),
    NAV_SAT_FIX: _msgdef(_NAV_SAT_FIX, *_HEADER_DEPS,
                         ("sensor_msgs/NavSatStatus", _NAV_SAT_STATUS)),
    TWIST_WITH_COVARIANCE_STAMPED: _msgdef(
        _TWIST_WITH_COVARIANCE_STAMPED, *_HEADER_DEPS,
        ("geometry_msgs/TwistWithCovariance", _TWIST_WITH_COVARIANCE),
        ("geometry_msgs/Twist", _TWIST), ("geometry_msgs/Vector3", _VECTOR3)),
}
"""Each message type's full definition (ros2msg schema text, dependencies appended)."""

UT_TO_T = 1e-6
STATUS_NO_FIX, STATUS_FIX = -1, 0
SERVICE_GPS = 1
COVARIANCE_TYPE_UNKNOWN, COVARIANCE_TYPE_DIAGONAL_KNOWN = 0, 2

# ---------------------------------------------------------------------------------------------
# Field helpers


def stamp(t_ns: int) -> dict[str, int]:
    """builtin_interfaces/Time of a nanosecond time stamp (nanosec in [0, 1e9))."""
    sec, nanosec = divmod(int(t_ns), 1_000_000_000)
    return {"sec": sec, "nanosec": nanosec}


def header(t_ns: int, frame_id: str) -> dict[str, Any]:
    return {"stamp": stamp(t_ns), "frame_id": frame_id}


def covariance3(stddev: float | None, *, absent: bool = False) -> list[float]:
    """A row-major 3x3 covariance: -1 first when the message carries no such value
    (``absent``), all zeros when its noise is unknown (``stddev`` None), else diagonal."""
    if absent:
        return [-1.0] + [0.0] * 8
    var = 0.0 if stddev is None else stddev * stddev
    return [var, 0.0, 0.0, 0.0, var, 0.0, 0.0, 0.0, var]


def _xyz(v: tuple[float, float, float] | None) -> dict[str, float]:
    if v is None:
        return {"x": 0.0, "y": 0.0, "z": 0.0}
    return {"x": float(v[0]), "y": float(v[1]), "z": float(v[2])}


def _flu(sample: VectorSample) -> tuple[float, float, float]:
    return express_sample(sample, ENU).vector


def quat_flu_to_enu(q_body_to_ned: tuple[float, float, float, float]
                    ) -> tuple[float, float, float, float]:
    """An imuhal attitude (body FRD -> NED, w first) as the ROS orientation (FLU -> ENU, w
    first), converted with the ``enu`` convention."""
    q = convert_quat(q_body_to_ned, NED, ENU)
    return (float(q[0]), float(q[1]), float(q[2]), float(q[3]))


# ---------------------------------------------------------------------------------------------
# Events -> messages


@dataclass(frozen=True, slots=True)
class RosRecord:
    """One message to write: its topic, type name (``sensor_msgs/msg/Imu``), the time it
    describes (``t_ns``, also in its header) and the message fields."""

    topic: str
    type: str
    t_ns: int
    message: dict[str, Any]


@dataclass
class _PendingImu:
    device: str
    t_ns: int
    accel: AccelSample | None = None
    gyro: GyroSample | None = None


@dataclass
class RosMessages:
    """Turns events into :class:`RosRecord` s (module docstring). Call :meth:`convert` for each
    event in the pipeline's order and :meth:`finish` at the end (a raw IMU message waits for
    the second half of its accelerometer/gyro pair)."""

    settings: RosSettings
    frame_id: str
    counts: dict[str, int] = field(default_factory=dict)
    """Messages produced per topic."""
    skipped: dict[str, int] = field(default_factory=dict)
    """Events not converted, by reason (``flagged``, ``sensor frame``)."""
    _primary: dict[str, str] = field(default_factory=dict)
    _pending: dict[str, _PendingImu] = field(default_factory=dict)
    _latest_accel: dict[str, AccelSample] = field(default_factory=dict)
    _latest_gyro: dict[str, GyroSample] = field(default_factory=dict)

    def _topic(self, kind: str, name: str, topic: str) -> str:
        """The plain topic for the first ``name`` of ``kind`` seen, ``name/topic`` after."""
        first = self._primary.setdefault(kind, name)
        return topic if first == name else f"{name}/{topic}"

    def _record(self, topic: str, type_: str, t_ns: int, message: dict[str, Any]) -> RosRecord:
        self.counts[topic] = self.counts.get(topic, 0) + 1
        return RosRecord(topic, type_, t_ns, message)

    def _skip(self, reason: str) -> None:
        self.skipped[reason] = self.skipped.get(reason, 0) + 1

    def convert(self, event: Event) -> Iterator[RosRecord]:
        """The records ``event`` completes (none, one, or two when it also closes an unpaired
        raw IMU message)."""
        if isinstance(event, AttitudeEstimate):
            yield self._estimate(event)
            return
        if not isinstance(event, Sample):
            return  # vertical estimates (no ROS type) and other estimators' outputs
        if not event.valid:
            self._skip("flagged")
            return
        if isinstance(event, VectorSample) and event.frame is not Frame.BODY_NED:
            self._skip("sensor frame")
            return
        if isinstance(event, AccelSample | GyroSample):
            yield from self._raw(event)
        elif isinstance(event, MagSample):
            yield self._record(
                self._topic("mag", event.device, "imu/mag"), MAGNETIC_FIELD, event.t_ns,
                {"header": header(event.t_ns, self.frame_id),
                 "magnetic_field": _xyz(tuple(x * UT_TO_T for x in _flu(event))),  # type: ignore[arg-type]  # _flu returns three components; the comprehension keeps three
                 "magnetic_field_covariance": covariance3(
                     None if self.settings.magnetic_field_stddev_ut is None
                     else self.settings.magnetic_field_stddev_ut * UT_TO_T)})
        elif isinstance(event, PressureSample):
            sd = self.settings.pressure_stddev_pa
            yield self._record(
                self._topic("pressure", event.device, "pressure"), FLUID_PRESSURE, event.t_ns,
                {"header": header(event.t_ns, self.frame_id),
                 "fluid_pressure": float(event.pressure_pa),
                 "variance": 0.0 if sd is None else sd * sd})
        elif isinstance(event, TemperatureSample):
            sd = self.settings.temperature_stddev_degc
            yield self._record(
                f"{event.device}/temperature", TEMPERATURE, event.t_ns,
                {"header": header(event.t_ns, self.frame_id),
                 "temperature": float(event.temperature_degc),
                 "variance": 0.0 if sd is None else sd * sd})
        elif isinstance(event, PositionSample):
            yield self._fix(event)
        elif isinstance(event, VelocitySample):
            yield self._velocity(event)

    def finish(self) -> Iterator[RosRecord]:
        """The raw IMU messages still waiting for their other half."""
        for device in list(self._pending):
            yield self._imu_raw(self._pending.pop(device))

    # -- IMU -----------------------------------------------------------------------------------

    def _raw(self, sample: AccelSample | GyroSample) -> Iterator[RosRecord]:
        # An accelerometer and a gyro read in one burst share a time stamp: one message holds
        # both. A half whose partner never comes is written alone, the missing quantity
        # marked -1 as REP-145 asks.
        device = sample.device
        pending = self._pending.get(device)
        if pending is not None and (pending.t_ns != sample.t_ns or getattr(
                pending, "accel" if isinstance(sample, AccelSample) else "gyro") is not None):
            yield self._imu_raw(self._pending.pop(device))
            pending = None
        if pending is None:
            pending = self._pending[device] = _PendingImu(device, sample.t_ns)
        if isinstance(sample, AccelSample):
            pending.accel = sample
            self._latest_accel[device] = sample
        else:
            pending.gyro = sample
            self._latest_gyro[device] = sample
        if pending.accel is not None and pending.gyro is not None:
            yield self._imu_raw(self._pending.pop(device))

    def _imu_fields(self, accel: AccelSample | None, gyro: GyroSample | None) -> dict[str, Any]:
        s = self.settings
        return {
            "angular_velocity": _xyz(_flu(gyro) if gyro is not None else None),
            "angular_velocity_covariance": covariance3(s.angular_velocity_stddev_rad_s,
                                                       absent=gyro is None),
            "linear_acceleration": _xyz(_flu(accel) if accel is not None else None),
            "linear_acceleration_covariance": covariance3(s.linear_acceleration_stddev_m_s2,
                                                          absent=accel is None),
        }

    def _imu_raw(self, p: _PendingImu) -> RosRecord:
        msg = {"header": header(p.t_ns, self.frame_id),
               "orientation": {"x": 0.0, "y": 0.0, "z": 0.0, "w": 0.0},
               "orientation_covariance": covariance3(None, absent=True),
               **self._imu_fields(p.accel, p.gyro)}
        return self._record(self._topic("imu", p.device, "imu/data_raw"), IMU, p.t_ns, msg)

    def _estimate(self, est: AttitudeEstimate) -> RosRecord:
        w, x, y, z = quat_flu_to_enu(est.q_body_to_ned)
        imu = self._primary.get("imu")
        accel = self._latest_accel.get(imu) if imu is not None else None
        gyro = self._latest_gyro.get(imu) if imu is not None else None
        msg = {"header": header(est.t_ns, self.frame_id),
               "orientation": {"x": x, "y": y, "z": z, "w": w},
               "orientation_covariance": covariance3(self.settings.orientation_stddev_rad),
               **self._imu_fields(accel, gyro)}
        return self._record(self._topic("attitude", est.source, "imu/data"), IMU, est.t_ns, msg)

    # -- GNSS ----------------------------------------------------------------------------------

    def _fix(self, pos: PositionSample) -> RosRecord:
        fixed = pos.fix_type in (FixType.FIX_2D, FixType.FIX_3D, FixType.GNSS_DEAD_RECKONING)
        # NavSatFix altitude is above the WGS-84 ellipsoid; a mean-sea-level height cannot be
        # converted without the geoid separation, which the receiver did not give: NaN, as
        # the interface asks when no altitude is available.
        altitude = pos.height_m if pos.height_datum is HeightDatum.ELLIPSOID else math.nan
        h, v = pos.horizontal_accuracy_m, pos.vertical_accuracy_m
        if h is not None:
            vz = v * v if v is not None else 0.0
            cov = [h * h, 0.0, 0.0, 0.0, h * h, 0.0, 0.0, 0.0, vz]
            kind = COVARIANCE_TYPE_DIAGONAL_KNOWN
        else:
            cov, kind = [0.0] * 9, COVARIANCE_TYPE_UNKNOWN
        return self._record(
            self._topic("fix", pos.device, "gps/fix"), NAV_SAT_FIX, pos.t_ns,
            {"header": header(pos.t_ns, self.frame_id),
             "status": {"status": STATUS_FIX if fixed else STATUS_NO_FIX,
                        "service": SERVICE_GPS},
             "latitude": float(pos.latitude_deg), "longitude": float(pos.longitude_deg),
             "altitude": float(altitude), "position_covariance": cov,
             "position_covariance_type": kind})

    def _velocity(self, vel: VelocitySample) -> RosRecord:
        ve, vn, vu = (float(c) for c in convert_earth_vector(vel.velocity_ned_m_s, NED, ENU))
        cov = [0.0] * 36
        if vel.accuracy_m_s is not None:
            for i in range(3):
                cov[i * 7] = vel.accuracy_m_s ** 2
        return self._record(
            self._topic("vel", vel.device, "gps/vel"), TWIST_WITH_COVARIANCE_STAMPED,
            vel.t_ns,
            {"header": header(vel.t_ns, self.frame_id),
             "twist": {"twist": {"linear": {"x": ve, "y": vn, "z": vu}, "angular": _xyz(None)},
                       "covariance": cov}})
