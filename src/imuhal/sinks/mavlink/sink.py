"""The MAVLink sink: the run's samples and estimates as MAVLink 2 messages over UDP.

Messages (common dialect, packed by ``pymavlink``), each at its rate in the run's time:

* ``HEARTBEAT`` at 1 Hz (type from the profile, autopilot generic, state active);
* ``HIGHRES_IMU`` at ``highres_imu_hz``, sent with a gyro sample of the first IMU: body frame
  FRD ("NED body frame", as MAVLink specifies), specific force in m/s^2 (level at rest:
  zacc = -9.81), rad/s, gauss (1 G = 100 uT), absolute pressure in hPa, the IMU's temperature
  in degC, pressure altitude in m (the vertical estimate); ``fields_updated`` flags the values
  that are new since the previous HIGHRES_IMU;
* ``SCALED_PRESSURE`` at ``pressure_hz`` (hPa, cdegC);
* ``ATTITUDE_QUATERNION`` at ``attitude_hz``: body FRD -> NED (w, x, y, z) and the body
  rates of the latest gyro sample;
* ``GLOBAL_POSITION_INT`` with every GNSS fix: degE7, altitude MSL and above the first fix
  in mm, NED ground speed in cm/s, heading from the attitude estimate in cdeg.

Time fields are the event's own time on the pipeline clock (``time_boot_ms``, ``time_usec``:
time since the run's clock started). Flagged samples are never sent. A datagram the network
refuses is counted in ``send_errors`` and the run goes on: a ground station coming and going
must not stop a logger.
"""

from __future__ import annotations

import math
import socket
from collections.abc import Mapping
from typing import Any, ClassVar

from pydantic import BaseModel, ConfigDict, Field, field_validator

from imuhal.core.conventions import NED, euler_deg_from_quat
from imuhal.core.errors import ImuhalError
from imuhal.core.samples import (
    AccelSample,
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
from imuhal.estimation.outputs import AttitudeEstimate, VerticalEstimate
from imuhal.sinks.base import Event, SinkPlugin
from imuhal.sinks.mavlink.settings import MavlinkSettings
from imuhal.sinks.pacing import RateLimiter

UT_PER_GAUSS = 100.0
PA_PER_HPA = 100.0
HEARTBEAT_HZ = 1.0
UINT16_MAX = 0xFFFF
MAV_AUTOPILOT_GENERIC = 0
MAV_STATE_ACTIVE = 4

# HIGHRES_IMU_UPDATED_FLAGS bits
_ACC, _GYRO, _MAG = 0b111, 0b111 << 3, 0b111 << 6
_ABS_PRESSURE, _PRESSURE_ALT, _TEMPERATURE = 1 << 9, 1 << 11, 1 << 12


def parse_udpout(spec: str) -> tuple[str, int]:
    """(host, port) of ``udpout:HOST:PORT``, or a one-line error naming the form."""
    kind, _, rest = spec.partition(":")
    host, _, port = rest.rpartition(":")
    host = host.strip("[]")
    if kind != "udpout" or not host or not port.isdigit() or not 0 < int(port) < 65536:
        raise ImuhalError(f"--mavlink {spec!r}: write udpout:HOST:PORT with a port 1-65535, "
                          "e.g. udpout:127.0.0.1:14550 (QGroundControl's port)")
    return host, int(port)


class MavlinkOutputSettings(BaseModel):
    """Where to send and the board's MAVLink identity and rates."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    output: str = "udpout:127.0.0.1:14550"
    """``udpout:HOST:PORT``: datagrams to a ground station listening there."""
    mavlink: MavlinkSettings = Field(default_factory=MavlinkSettings)
    """Ids and rates (``imuhal run`` passes the profile's ``outputs.mavlink`` section)."""
    attitude_source: str | None = None
    """The attitude estimator sent (default: the first seen)."""
    vertical_source: str | None = None
    """The vertical estimator whose altitude is HIGHRES_IMU's pressure_alt (default: first)."""

    @field_validator("output")
    @classmethod
    def _udpout(cls, value: str) -> str:
        parse_udpout(value)
        return value


def _mavlink_dialect() -> Any:
    try:
        from pymavlink.dialects.v20 import common
    except ImportError:
        raise ImuhalError("--mavlink needs the 'mavlink' extra (pymavlink is missing): "
                          "pip install 'imuhal[mavlink]'") from None
    return common


class _Datagrams:
    """The file-like pymavlink writes packed messages to: one UDP datagram each."""

    def __init__(self, host: str, port: int) -> None:
        try:
            family, kind, proto, _, addr = socket.getaddrinfo(host, port,
                                                              type=socket.SOCK_DGRAM)[0]
        except OSError as exc:
            raise ImuhalError(f"--mavlink udpout:{host}:{port}: cannot resolve {host} "
                              f"({exc}); give an address such as 127.0.0.1") from None
        self.address = addr
        self.sock = socket.socket(family, kind, proto)
        self.sent = 0
        self.errors = 0

    def write(self, data: bytes) -> None:
        try:
            self.sock.sendto(data, self.address)
            self.sent += 1
        except OSError:
            self.errors += 1

    def close(self) -> None:
        self.sock.close()


class MavlinkSink(SinkPlugin):
    """Sends MAVLink 2 messages over UDP (module docstring). ``counts`` says how many of each
    message went out."""

    name: ClassVar[str] = "mavlink"
    description: ClassVar[str] = ("MAVLink 2 over UDP to a ground station: HEARTBEAT, "
                                  "HIGHRES_IMU, SCALED_PRESSURE, ATTITUDE_QUATERNION, "
                                  "GLOBAL_POSITION_INT")
    Settings = MavlinkOutputSettings

    def __init__(self, settings: MavlinkOutputSettings | Mapping[str, Any] | None = None
                 ) -> None:
        super().__init__(settings)
        self.settings: MavlinkOutputSettings
        s = self.settings
        dialect = _mavlink_dialect()
        self._out = _Datagrams(*parse_udpout(s.output))
        self._mav = dialect.MAVLink(self._out, srcSystem=s.mavlink.system_id,
                                    srcComponent=s.mavlink.component_id)
        self.counts: dict[str, int] = {}
        self._pacing = RateLimiter()
        self._imu: str | None = None
        self._accel: VectorSample | None = None
        self._gyro: VectorSample | None = None
        self._mag: VectorSample | None = None
        self._pressure: PressureSample | None = None
        self._baro_temperature: float | None = None
        self._imu_temperature: float | None = None
        self._vertical: VerticalEstimate | None = None
        self._attitude: AttitudeEstimate | None = None
        self._velocity: VelocitySample | None = None
        self._home_alt_m: float | None = None
        self._updated = 0
        self.skipped_fixes = 0
        """GNSS fixes not sent: no height above mean sea level, or a coordinate missing."""

    @property
    def send_errors(self) -> int:
        return self._out.errors

    # -- events ---------------------------------------------------------------------------------

    def handle(self, event: Event) -> None:
        self._heartbeat(event.t_ns)
        if isinstance(event, AttitudeEstimate):
            self._on_attitude(event)
        elif isinstance(event, VerticalEstimate):
            src = self.settings.vertical_source
            if src is None or src == event.source:
                if src is None:
                    self.settings = self.settings.model_copy(
                        update={"vertical_source": event.source})
                self._vertical = event
                self._updated |= _PRESSURE_ALT
        elif isinstance(event, Sample) and event.valid:
            self._on_sample(event)

    def _on_sample(self, sample: Sample) -> None:
        if isinstance(sample, VectorSample) and sample.frame is not Frame.BODY_NED:
            return  # no body axes: MAVLink's IMU fields are body-frame
        if isinstance(sample, AccelSample | GyroSample):
            if self._imu is None:
                self._imu = sample.device
            if sample.device != self._imu:
                return
            if isinstance(sample, AccelSample):
                self._accel = sample
                self._updated |= _ACC
            else:
                self._gyro = sample
                self._updated |= _GYRO
                if self._due("HIGHRES_IMU", sample.t_ns, self.settings.mavlink.highres_imu_hz):
                    self._highres_imu(sample.t_ns)
        elif isinstance(sample, MagSample):
            self._mag = sample
            self._updated |= _MAG
        elif isinstance(sample, PressureSample):
            self._pressure = sample
            self._updated |= _ABS_PRESSURE
            if self._due("SCALED_PRESSURE", sample.t_ns, self.settings.mavlink.pressure_hz):
                self._send("SCALED_PRESSURE", self._mav.scaled_pressure_encode(
                    _ms(sample.t_ns), sample.pressure_pa / PA_PER_HPA, 0.0,
                    _cdegc(self._baro_temperature)))
        elif isinstance(sample, TemperatureSample):
            if self._pressure is not None and sample.device == self._pressure.device:
                self._baro_temperature = sample.temperature_degc
            if sample.device == self._imu:
                self._imu_temperature = sample.temperature_degc
                self._updated |= _TEMPERATURE
        elif isinstance(sample, VelocitySample):
            self._velocity = sample
        elif isinstance(sample, PositionSample):
            self._global_position(sample)

    def _due(self, name: str, t_ns: int, rate_hz: float) -> bool:
        return self._pacing.due(name, t_ns, rate_hz)

    def _send(self, name: str, msg: Any) -> None:
        self._mav.send(msg)
        self.counts[name] = self.counts.get(name, 0) + 1

    # -- messages -------------------------------------------------------------------------------

    def _heartbeat(self, t_ns: int) -> None:
        if not self._pacing.due("HEARTBEAT", t_ns, HEARTBEAT_HZ):
            return
        self._send("HEARTBEAT", self._mav.heartbeat_encode(
            self.settings.mavlink.mav_type, MAV_AUTOPILOT_GENERIC, 0, 0, MAV_STATE_ACTIVE))

    def _highres_imu(self, t_ns: int) -> None:
        acc = self._accel.vector if self._accel is not None else (0.0, 0.0, 0.0)
        gyro = self._gyro.vector if self._gyro is not None else (0.0, 0.0, 0.0)
        mag = tuple(v / UT_PER_GAUSS for v in self._mag.vector) if self._mag is not None \
            else (0.0, 0.0, 0.0)
        pressure = self._pressure.pressure_pa / PA_PER_HPA if self._pressure is not None \
            else 0.0
        alt = self._vertical.altitude_m if self._vertical is not None else 0.0
        temp = self._imu_temperature if self._imu_temperature is not None else 0.0
        self._send("HIGHRES_IMU", self._mav.highres_imu_encode(
            t_ns // 1000, *acc, *gyro, *mag, pressure, 0.0, alt, temp, self._updated, 0))
        self._updated = 0

    def _on_attitude(self, est: AttitudeEstimate) -> None:
        src = self.settings.attitude_source
        if src is None:
            self.settings = self.settings.model_copy(update={"attitude_source": est.source})
        elif src != est.source:
            return
        self._attitude = est
        if not self._due("ATTITUDE_QUATERNION", est.t_ns, self.settings.mavlink.attitude_hz):
            return
        p, q, r = self._gyro.vector if self._gyro is not None else (0.0, 0.0, 0.0)
        self._send("ATTITUDE_QUATERNION", self._mav.attitude_quaternion_encode(
            _ms(est.t_ns), *est.q_body_to_ned, p, q, r))

    def _global_position(self, pos: PositionSample) -> None:
        if pos.height_datum is not HeightDatum.MSL or not all(
                math.isfinite(x) for x in (pos.latitude_deg, pos.longitude_deg, pos.height_m)):
            # GLOBAL_POSITION_INT has no "unknown" for these, and its altitude is MSL: an
            # ellipsoid height is not it
            self.skipped_fixes += 1
            return
        if self._home_alt_m is None:
            self._home_alt_m = pos.height_m
        vn, ve, vd = self._velocity.velocity_ned_m_s if self._velocity is not None \
            else (0.0, 0.0, 0.0)
        hdg = UINT16_MAX
        if self._attitude is not None:
            yaw = euler_deg_from_quat(NED, self._attitude.q_body_to_ned).yaw
            hdg = round((yaw % 360.0) * 100) % 36000
        self._send("GLOBAL_POSITION_INT", self._mav.global_position_int_encode(
            _ms(pos.t_ns), round(pos.latitude_deg * 1e7), round(pos.longitude_deg * 1e7),
            round(pos.height_m * 1000), round((pos.height_m - self._home_alt_m) * 1000),
            _cm_s(vn), _cm_s(ve), _cm_s(vd), hdg))

    def close(self) -> None:
        self._out.close()


def _ms(t_ns: int) -> int:
    """time_boot_ms (uint32: wraps after 49.7 days, as on any autopilot)."""
    return (t_ns // 1_000_000) & 0xFFFFFFFF


def _cdegc(temperature_degc: float | None) -> int:
    if temperature_degc is None or not math.isfinite(temperature_degc):
        return 0
    return max(-32768, min(32767, round(temperature_degc * 100)))


def _cm_s(v_m_s: float) -> int:
    if not math.isfinite(v_m_s):
        return 0
    return max(-32768, min(32767, round(v_m_s * 100)))
