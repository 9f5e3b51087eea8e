"""Encoders of the sentences flight apps read. Pure functions: values in SI, text out.

Each format's units are the ones its reader expects (docs/flight-instrument.md cites the
parsers): LK8EX1 pressure in Pa, vario in cm/s; POV pressure in hPa, vario in m/s; LXWP0
pressure altitude in m, vario in m/s, speeds in km/h; _PRS
pressure in Pa as hexadecimal; XCTRC raw pressure in hPa, speed in m/s (as XCSoar reads it);
GGA/RMC the NMEA 0183 units (ddmm.mmmm, knots, metres).
"""

from __future__ import annotations

import math
from datetime import datetime

KNOTS_PER_M_S = 3600.0 / 1852.0


def checksum(body: str) -> str:
    """The NMEA checksum of ``body`` (the text between ``$`` and ``*``): XOR of its bytes,
    two upper-case hex digits."""
    value = 0
    for byte in body.encode("ascii"):
        value ^= byte
    return f"{value:02X}"


def sentence(body: str) -> str:
    """``$body*CS`` and CR LF."""
    return f"${body}*{checksum(body)}\r\n"


def _fmt(value: float | None, spec: str) -> str:
    return "" if value is None or not math.isfinite(value) else format(value, spec)


def lk8ex1(*, pressure_pa: float | None, altitude_m: float | None, climb_m_s: float | None,
           temperature_degc: float | None, battery_v: float | None = None,
           battery_percent: float | None = None) -> str:
    """``$LK8EX1,pressure,altitude,vario,temperature,battery,*CS``: pressure Pa (integer,
    999999 = none), altitude m (integer, 99999 = none), vario cm/s (integer, 9999 = none),
    temperature degC (integer, 99 = none), battery volts or 1000 + percent (999 = none)."""
    p = "999999" if pressure_pa is None else str(round(pressure_pa))
    a = "99999" if altitude_m is None else str(round(altitude_m))
    v = "9999" if climb_m_s is None else str(round(climb_m_s * 100.0))
    t = "99" if temperature_degc is None else str(round(temperature_degc))
    if battery_percent is not None:
        b = f"{1000 + round(battery_percent)}"
    elif battery_v is not None:
        b = f"{battery_v:.2f}"
    else:
        b = "999"
    return sentence(f"LK8EX1,{p},{a},{v},{t},{b},")


def pov(*, pressure_pa: float | None = None, temperature_degc: float | None = None,
        battery_v: float | None = None, true_airspeed_m_s: float | None = None,
        te_vario_m_s: float | None = None) -> str:
    """OpenVario ``$POV,P,hPa,S,km/h,E,m/s,T,degC,V,volts*CS``: key-value pairs, absent
    ones left out. ``E`` is the total-energy vario: only sent with the true airspeed it is
    compensated with (``S``); without one XCSoar computes its own vario from ``P``, which a
    plain climb rate labelled total energy would override."""
    parts = ["POV"]
    if pressure_pa is not None:
        parts += ["P", f"{pressure_pa / 100.0:.2f}"]
    if true_airspeed_m_s is not None:
        parts += ["S", f"{true_airspeed_m_s * 3.6:.1f}"]
        if te_vario_m_s is not None:
            parts += ["E", f"{te_vario_m_s:.2f}"]
    if temperature_degc is not None:
        parts += ["T", f"{temperature_degc:.2f}"]
    if battery_v is not None:
        parts += ["V", f"{battery_v:.2f}"]
    return sentence(",".join(parts))


def lxwp0(*, logger_recording: bool = False, true_airspeed_m_s: float | None = None,
          pressure_altitude_m: float | None = None, climb_m_s: float | None = None,
          heading_deg: float | None = None, wind_from_deg: float | None = None,
          wind_speed_m_s: float | None = None) -> str:
    """LX ``$LXWP0,logger,TAS,altitude,vario,,,,,,heading,wind direction,wind speed*CS``
    as XCSoar's LX parser (Driver/LX/Parser.cpp) reads it: logger recording Y/N, true
    airspeed km/h, pressure altitude m above the 1013.25 hPa datum, vario m/s, five more
    vario slots (an LX fills them with the rest of the second's samples; left empty: each
    sentence carries one fresh value, XCSoar reads only the first), heading deg, the
    direction the wind blows from deg, wind speed km/h. Absent values are empty fields."""
    fields = ["Y" if logger_recording else "N",
              _fmt(None if true_airspeed_m_s is None else true_airspeed_m_s * 3.6, ".1f"),
              _fmt(pressure_altitude_m, ".1f"), _fmt(climb_m_s, ".2f"), "", "", "", "", "",
              _fmt(None if heading_deg is None else heading_deg % 360.0, ".0f"),
              _fmt(None if wind_from_deg is None else wind_from_deg % 360.0, ".0f"),
              _fmt(None if wind_speed_m_s is None else wind_speed_m_s * 3.6, ".1f")]
    return sentence("LXWP0," + ",".join(fields))


def prs(pressure_pa: float) -> str:
    """FlyNet ``_PRS XXXXXXXX``: static pressure in Pa, 8 hexadecimal digits, no checksum."""
    return f"_PRS {round(pressure_pa):08X}\n"


def xctrc(*, utc: datetime, latitude_deg: float | None, longitude_deg: float | None,
          gps_altitude_m: float | None, ground_speed_m_s: float | None,
          course_deg: float | None, climb_m_s: float | None, pressure_pa: float | None,
          battery_percent: float | None) -> str:
    """XC Tracer ``$XCTRC,year,month,day,hour,minute,second,centisecond,lat,lon,altitude,
    speed,course,climb,,,,raw pressure (hPa),battery (%)*CS``: decimal degrees, m, m/s."""
    cs = utc.microsecond // 10_000
    fields = [
        "XCTRC", str(utc.year), str(utc.month), str(utc.day), str(utc.hour), str(utc.minute),
        str(utc.second), str(cs), _fmt(latitude_deg, ".6f"), _fmt(longitude_deg, ".6f"),
        _fmt(gps_altitude_m, ".2f"), _fmt(ground_speed_m_s, ".2f"), _fmt(course_deg, ".2f"),
        _fmt(climb_m_s, ".2f"), "", "", "",
        "" if pressure_pa is None else f"{pressure_pa / 100.0:.2f}",
        "" if battery_percent is None else str(round(battery_percent)),
    ]
    return sentence(",".join(fields))


def _lat(lat_deg: float) -> tuple[str, str]:
    hemi = "N" if lat_deg >= 0 else "S"
    a = abs(lat_deg)
    deg = int(a)
    minutes = (a - deg) * 60.0
    if round(minutes, 4) >= 60.0:  # 59.99999 rounds up to the next degree
        deg, minutes = deg + 1, 0.0
    return f"{deg:02d}{minutes:07.4f}", hemi


def _lon(lon_deg: float) -> tuple[str, str]:
    hemi = "E" if lon_deg >= 0 else "W"
    a = abs(lon_deg)
    deg = int(a)
    minutes = (a - deg) * 60.0
    if round(minutes, 4) >= 60.0:
        deg, minutes = deg + 1, 0.0
    return f"{deg:03d}{minutes:07.4f}", hemi


def _time(utc: datetime) -> str:
    return f"{utc:%H%M%S}.{utc.microsecond // 10_000:02d}"


def gga(*, utc: datetime, latitude_deg: float, longitude_deg: float, quality: int,
        satellites: int, hdop: float | None, altitude_msl_m: float,
        geoid_separation_m: float | None,
        talker: str = "GP") -> str:
    """``$GPGGA``: time, position (ddmm.mmmm), fix quality (0 none, 1 GPS, 2 DGPS),
    satellites used, HDOP, altitude above MSL (m), geoid separation (m; empty when
    unknown)."""
    lat, ns = _lat(latitude_deg)
    lon, ew = _lon(longitude_deg)
    body = (f"{talker}GGA,{_time(utc)},{lat},{ns},{lon},{ew},{quality},{satellites:02d},"
            f"{_fmt(hdop, '.1f')},{altitude_msl_m:.1f},M,{_fmt(geoid_separation_m, '.1f')},M,,")
    return sentence(body)


def rmc(*, utc: datetime, valid: bool, latitude_deg: float, longitude_deg: float,
        ground_speed_m_s: float, course_deg: float, talker: str = "GP") -> str:
    """``$GPRMC``: time, status (A valid / V warning), position, speed over ground in
    knots, course over ground (deg true), date ddmmyy, no magnetic variation; mode A/N."""
    lat, ns = _lat(latitude_deg)
    lon, ew = _lon(longitude_deg)
    body = (f"{talker}RMC,{_time(utc)},{'A' if valid else 'V'},{lat},{ns},{lon},{ew},"
            f"{ground_speed_m_s * KNOTS_PER_M_S:.2f},{course_deg % 360.0:.2f},"
            f"{utc:%d%m%y},,,{'A' if valid else 'N'}")
    return sentence(body)


def vtg(*, ground_speed_m_s: float, course_deg: float, talker: str = "GP") -> str:
    """``$GPVTG``: course (true), speed in knots and km/h, mode A."""
    return sentence(f"{talker}VTG,{course_deg % 360.0:.2f},T,,M,"
                    f"{ground_speed_m_s * KNOTS_PER_M_S:.2f},N,{ground_speed_m_s * 3.6:.2f},K,A")


def gsa(*, fix: int, satellite_ids: list[int], pdop: float, hdop: float, vdop: float,
        talker: str = "GP") -> str:
    """``$GPGSA``: mode A (automatic), fix 1 none / 2 2D / 3 3D, up to 12 satellite IDs,
    PDOP, HDOP, VDOP."""
    ids = [f"{s:02d}" for s in satellite_ids[:12]] + [""] * (12 - min(12, len(satellite_ids)))
    return sentence(f"{talker}GSA,A,{fix},{','.join(ids)},{pdop:.1f},{hdop:.1f},{vdop:.1f}")


def course_and_speed(velocity_ned_m_s: tuple[float, float, float]) -> tuple[float, float]:
    """(course over ground deg true in [0, 360), ground speed m/s) of a NED velocity."""
    n, e, _ = velocity_ned_m_s
    return math.degrees(math.atan2(e, n)) % 360.0, math.hypot(n, e)
