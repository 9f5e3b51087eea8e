"""The flight-app sink: the run's estimates as LK8EX1, LXWP0, POV, _PRS, XCTRC, GGA
and RMC.

Values come from the latest events of their kind: static pressure and the barometer's
temperature (valid samples of the device that gives pressure), altitude and climb rate from
one vertical estimator (``source``, default the first seen), position and velocity from the
GNSS samples. Flagged samples are never sent. Each sentence has its own rate limit in the
run's time (simulated or real), so an app sees the rates its format expects.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from datetime import datetime, timezone
from typing import Any, ClassVar

from pydantic import BaseModel, ConfigDict, Field

from imuhal.core.atmosphere import altitude_m_from_pressure
from imuhal.core.errors import ImuhalError
from imuhal.core.samples import (
    FixType,
    PositionSample,
    PressureSample,
    Sample,
    TemperatureSample,
    VelocitySample,
)
from imuhal.estimation.outputs import VerticalEstimate
from imuhal.sinks.base import Event, SinkPlugin
from imuhal.sinks.flight import sentences as fmt
from imuhal.sinks.flight.transports import Transport, open_transport
from imuhal.sinks.pacing import RateLimiter

SENTENCES = ("LK8EX1", "LXWP0", "POV", "PRS", "XCTRC", "GGA", "RMC")


def check_sentences(names: tuple[str, ...], given_as: str = "") -> None:
    """An ImuhalError naming the sentences imuhal does not write, if any (``given_as``: the
    input they came from, e.g. the CLI option, to start the message with)."""
    unknown = set(names) - set(SENTENCES)
    if unknown:
        raise ImuhalError(f"{given_as + ': ' if given_as else ''}unknown flight sentences "
                          f"{sorted(unknown)}; known: {', '.join(SENTENCES)}")


class FlightOutputSettings(BaseModel):
    """Where to send, which sentences and how often (Hz; 0 = with every new value)."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    output: str = "pty"
    """serial:PORT@BAUD, pty, pty:LINK, tcp:PORT or tcp:HOST:PORT (transports.py)."""
    sentences: tuple[str, ...] = SENTENCES
    lk8ex1_hz: float = Field(10.0, ge=0)
    lxwp0_hz: float = Field(10.0, ge=0)
    """10 Hz with one fresh vario value each (an LX sends 1 Hz with six: up to 1 s stale)."""
    pov_hz: float = Field(10.0, ge=0)
    prs_hz: float = Field(1 / 0.048, ge=0)
    """FlyNet sends _PRS every 48 ms (XCSoar's FlyNet driver assumes that rate)."""
    xctrc_hz: float = Field(10.0, ge=0)
    gps_hz: float = Field(0.0, ge=0)
    """GGA/RMC: 0 = one pair per GNSS epoch."""
    source: str | None = None
    """The vertical estimator whose altitude and climb are sent (default: the first seen)."""
    battery_v: float | None = None
    battery_percent: float | None = Field(None, ge=0, le=100)


class FlightSink(SinkPlugin):
    """Writes sentences to a :class:`Transport` (``settings.output``, or one handed over);
    ``counts`` says how many of each went out."""

    name: ClassVar[str] = "nmea"
    description: ClassVar[str] = ("LK8EX1, LXWP0, POV, _PRS, XCTRC, GGA, RMC to a flight app over "
                                  "serial, a pty or TCP")
    Settings = FlightOutputSettings

    def __init__(self, settings: FlightOutputSettings | Mapping[str, Any] | None = None, *,
                 transport: Transport | None = None) -> None:
        super().__init__(settings)
        self.settings: FlightOutputSettings
        check_sentences(self.settings.sentences)
        self.transport = transport if transport is not None else \
            open_transport(self.settings.output)
        self.counts = dict.fromkeys(SENTENCES, 0)
        self._set_pressure = getattr(self.transport, "set_pressure_pa", None)
        self._pacing = RateLimiter()
        self._pressure: PressureSample | None = None
        self._temperature: float | None = None
        self._vertical: VerticalEstimate | None = None
        self._position: PositionSample | None = None
        self._velocity: VelocitySample | None = None

    def handle(self, event: Event) -> None:
        if isinstance(event, Sample):
            if not event.valid:
                return
            if isinstance(event, PressureSample):
                self._pressure = event
                self._maybe("PRS", event.t_ns)
                if self._set_pressure is not None:  # a BLE transport's ESS characteristic
                    self._set_pressure(event.pressure_pa, event.t_ns)
            elif isinstance(event, TemperatureSample):
                if self._pressure is not None and event.device == self._pressure.device:
                    self._temperature = event.temperature_degc
            elif isinstance(event, VelocitySample):
                self._velocity = event
            elif isinstance(event, PositionSample) and \
                    event.fix_type in (FixType.FIX_2D, FixType.FIX_3D):
                self._position = event
                self._maybe("GGA", event.t_ns)
                self._maybe("RMC", event.t_ns)
            return
        if isinstance(event, VerticalEstimate):
            if self.settings.source is None:
                self.settings = self.settings.model_copy(update={"source": event.source})
            if event.source != self.settings.source:
                return
            self._vertical = event
            for name in ("LK8EX1", "LXWP0", "POV", "XCTRC"):
                self._maybe(name, event.t_ns)

    def _rate(self, name: str) -> float:
        s = self.settings
        return {"LK8EX1": s.lk8ex1_hz, "LXWP0": s.lxwp0_hz, "POV": s.pov_hz, "PRS": s.prs_hz,
                "XCTRC": s.xctrc_hz, "GGA": s.gps_hz, "RMC": s.gps_hz}[name]

    def _maybe(self, name: str, t_ns: int) -> None:
        if name not in self.settings.sentences:
            return
        rate = self._rate(name)
        if not self._pacing.ready(name, t_ns, rate):
            return
        text = self._encode(name)
        if text is None:
            return
        self._pacing.mark(name, t_ns, rate)
        self.counts[name] += 1
        self.transport.write(text.encode("ascii"))

    def _encode(self, name: str) -> str | None:
        """Sentence ``name`` from the latest values, or None while one it needs is missing."""
        return _ENCODERS[name](self)

    def _pressure_pa(self) -> float | None:
        return self._pressure.pressure_pa if self._pressure is not None else None

    def _prs(self) -> str | None:
        p = self._pressure_pa()
        return None if p is None else fmt.prs(p)

    def _lk8ex1(self) -> str | None:
        v, s = self._vertical, self.settings
        if v is None:
            return None
        return fmt.lk8ex1(pressure_pa=self._pressure_pa(), altitude_m=v.altitude_m,
                          climb_m_s=v.climb_m_s, temperature_degc=self._temperature,
                          battery_v=s.battery_v, battery_percent=s.battery_percent)

    def _lxwp0(self) -> str | None:
        v, p = self._vertical, self._pressure_pa()
        if v is None:
            return None
        return fmt.lxwp0(
            pressure_altitude_m=altitude_m_from_pressure(p) if p is not None else None,
            climb_m_s=v.climb_m_s)

    def _pov(self) -> str | None:
        if self._vertical is None:
            return None
        # No airspeed source: no total energy (E), so XCSoar derives its vario from P.
        return fmt.pov(pressure_pa=self._pressure_pa(), temperature_degc=self._temperature,
                       battery_v=self.settings.battery_v)

    def _fix(self) -> tuple[PositionSample, datetime] | None:
        """The latest position and its UTC time, or None without one."""
        pos = self._position
        utc = self._utc(pos) if pos is not None else None
        return None if pos is None or utc is None else (pos, utc)

    def _xctrc(self) -> str | None:
        v, fix = self._vertical, self._fix()
        if v is None or fix is None:
            return None
        pos, utc = fix
        course, speed = self._course_speed()
        return fmt.xctrc(
            utc=utc, latitude_deg=pos.latitude_deg, longitude_deg=pos.longitude_deg,
            gps_altitude_m=pos.height_m, ground_speed_m_s=speed, course_deg=course,
            climb_m_s=v.climb_m_s, pressure_pa=self._pressure_pa(),
            battery_percent=self.settings.battery_percent)

    def _gga(self) -> str | None:
        fix = self._fix()
        if fix is None:
            return None
        pos, utc = fix
        return fmt.gga(utc=utc, latitude_deg=pos.latitude_deg,
                       longitude_deg=pos.longitude_deg, quality=1,
                       satellites=pos.satellites, hdop=None,
                       altitude_msl_m=pos.height_m, geoid_separation_m=None)

    def _rmc(self) -> str | None:
        fix = self._fix()
        if fix is None:
            return None
        pos, utc = fix
        course, speed = self._course_speed()
        return fmt.rmc(utc=utc, valid=True, latitude_deg=pos.latitude_deg,
                       longitude_deg=pos.longitude_deg, ground_speed_m_s=speed or 0.0,
                       course_deg=course or 0.0)

    def _course_speed(self) -> tuple[float | None, float | None]:
        if self._velocity is None:
            return None, None
        return fmt.course_and_speed(self._velocity.velocity_ned_m_s)

    @staticmethod
    def _utc(pos: PositionSample) -> datetime | None:
        if pos.utc_s is None or not math.isfinite(pos.utc_s):
            return None
        return datetime.fromtimestamp(pos.utc_s, tz=timezone.utc)

    def close(self) -> None:
        self.transport.close()


_ENCODERS: dict[str, Callable[[FlightSink], str | None]] = {
    "PRS": FlightSink._prs, "LK8EX1": FlightSink._lk8ex1, "LXWP0": FlightSink._lxwp0,
    "POV": FlightSink._pov, "XCTRC": FlightSink._xctrc, "GGA": FlightSink._gga,
    "RMC": FlightSink._rmc,
}
"""Each sentence's encoder, by its name in SENTENCES."""
