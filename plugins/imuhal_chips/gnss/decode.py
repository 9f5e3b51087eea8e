"""Decoding what a receiver sends: NMEA through pynmea2, UBX NAV-PVT through pyubx2.

Pure functions from one sentence or frame to a :class:`Epoch` fragment in SI units. A bad
checksum is reported as such (``checksum_ok=False``) with whatever could still be read, so
the driver can flag and count it; it is never merged into a fix.
"""

from __future__ import annotations

import math
import struct
from dataclasses import dataclass
from datetime import date, time
from typing import Any

from imuhal.core.samples import FixType

KNOT_M_S = 1852.0 / 3600.0


class DecodeError(ValueError):
    """A sentence or frame that cannot be read at all (garbled beyond its checksum)."""


@dataclass
class Fragment:
    """What one sentence or frame says about an epoch (None: it does not say)."""

    kind: str
    """Message name: GGA, RMC, VTG, GSA, NAV-PVT, ACK-ACK, ACK-NAK, or another."""
    checksum_ok: bool = True
    time_of_day_s: float | None = None
    """UTC time of day, s."""
    gps_time_of_week_s: float | None = None
    """GPS time of week of the navigation epoch (NAV-PVT iTOW), s."""
    day: date | None = None
    latitude_deg: float | None = None
    longitude_deg: float | None = None
    height_msl_m: float | None = None
    height_ellipsoid_m: float | None = None
    fix_type: FixType | None = None
    satellites: int | None = None
    hdop: float | None = None
    ground_speed_m_s: float | None = None
    course_deg: float | None = None
    velocity_ned_m_s: tuple[float, float, float] | None = None
    horizontal_accuracy_m: float | None = None
    vertical_accuracy_m: float | None = None
    speed_accuracy_m_s: float | None = None
    acked: tuple[int, int] | None = None
    """ACK-ACK / ACK-NAK: the (class, id) of the acknowledged message."""
    inconsistent: str = ""
    """Why a frame whose checksum passed still failed its integrity check (then
    ``checksum_ok`` is False and nothing else is read); empty when it did not."""


def _f(text: Any) -> float | None:
    try:
        value = float(text)
    except (TypeError, ValueError):
        return None
    return value if math.isfinite(value) else None


def _tod(t: time | None) -> float | None:
    if t is None:
        return None
    return t.hour * 3600 + t.minute * 60 + t.second + t.microsecond / 1e6


_GGA_FIX = {0: FixType.NO_FIX, 1: FixType.FIX_3D, 2: FixType.FIX_3D, 4: FixType.FIX_3D,
            5: FixType.FIX_3D, 6: FixType.DEAD_RECKONING}


def decode_nmea(line: bytes) -> Fragment:
    """One NMEA sentence (with or without CR LF). Raises DecodeError when unreadable."""
    import pynmea2

    try:
        text = line.decode("ascii").strip()
    except UnicodeDecodeError as exc:
        raise DecodeError(f"not ASCII: {line[:20]!r}") from exc
    checksum_ok = True
    try:
        msg = pynmea2.parse(text, check=True)
    except pynmea2.ChecksumError:
        checksum_ok = False
        try:
            # pynmea2 rejects a wrong checksum even unchecked: read the fields without it.
            msg = pynmea2.parse(text.rsplit("*", 1)[0], check=False)
        except pynmea2.ParseError as exc:
            raise DecodeError(str(exc)) from exc
    except pynmea2.ParseError as exc:
        raise DecodeError(str(exc)) from exc
    kind = getattr(msg, "sentence_type", "") or type(msg).__name__
    frag = Fragment(kind=kind, checksum_ok=checksum_ok)
    try:
        _fill(frag, msg)
    except (ValueError, TypeError, AttributeError) as exc:
        raise DecodeError(f"{kind}: {exc}") from exc
    return frag


def _fill(frag: Fragment, msg: Any) -> None:
    # msg: a pynmea2 sentence, whose fields pynmea2 creates at run time (no types)
    kind = frag.kind
    if kind == "GGA":
        qual = int(getattr(msg, "gps_qual", 0) or 0)
        frag.time_of_day_s = _tod(msg.timestamp)
        frag.fix_type = _GGA_FIX.get(qual, FixType.NO_FIX)
        frag.satellites = int(msg.num_sats or 0)
        frag.hdop = _f(msg.horizontal_dil)
        if qual:
            frag.latitude_deg = float(msg.latitude)
            frag.longitude_deg = float(msg.longitude)
            frag.height_msl_m = _f(msg.altitude)
            sep = _f(msg.geo_sep)
            if frag.height_msl_m is not None and sep is not None:
                frag.height_ellipsoid_m = frag.height_msl_m + sep
    elif kind == "RMC":
        frag.time_of_day_s = _tod(msg.timestamp)
        frag.day = msg.datestamp
        if msg.status == "A":
            frag.latitude_deg = float(msg.latitude)
            frag.longitude_deg = float(msg.longitude)
            knots = _f(msg.spd_over_grnd)
            frag.ground_speed_m_s = None if knots is None else knots * KNOT_M_S
            frag.course_deg = _f(msg.true_course)
    elif kind == "VTG":
        knots = _f(msg.spd_over_grnd_kts)
        frag.ground_speed_m_s = None if knots is None else knots * KNOT_M_S
        frag.course_deg = _f(msg.true_track)
    elif kind == "GSA":
        mode = int(msg.mode_fix_type or 1)
        frag.fix_type = {1: FixType.NO_FIX, 2: FixType.FIX_2D, 3: FixType.FIX_3D}.get(
            mode, FixType.NO_FIX)
        frag.hdop = _f(msg.hdop)


def decode_ubx(frame: bytes) -> Fragment:
    """One UBX frame. A bad checksum gives ``checksum_ok=False`` (nothing else read); an
    unreadable frame raises DecodeError."""
    import pyubx2

    try:
        msg = pyubx2.UBXReader.parse(frame, validate=pyubx2.VALCKSUM)
    except pyubx2.UBXParseError as exc:
        if "checksum" in str(exc).lower():
            return Fragment(kind="UBX", checksum_ok=False)
        raise DecodeError(str(exc)) from exc
    except (pyubx2.UBXMessageError, pyubx2.UBXTypeError, ValueError) as exc:
        raise DecodeError(str(exc)) from exc
    except (IndexError, KeyError, TypeError, struct.error) as exc:
        # pyubx2 indexing past a payload whose repeated groups do not fit its length (a
        # frame with a good checksum and a garbled body): unreadable, not a crash
        raise DecodeError(f"unreadable UBX frame ({type(exc).__name__}: {exc})") from exc
    ident = msg.identity
    if ident in ("ACK-ACK", "ACK-NAK"):
        return Fragment(kind=ident, acked=(int(msg.clsID), int(msg.msgID)))
    if ident != "NAV-PVT":
        return Fragment(kind=ident)
    try:
        frag = _nav_pvt(msg, ident)
    except (ValueError, TypeError, AttributeError) as exc:
        # a frame with a good checksum holding impossible fields (month 13, day 0)
        raise DecodeError(f"{ident}: {exc}") from exc
    why = _nav_pvt_inconsistency(frag)
    return Fragment(kind=ident, checksum_ok=False, inconsistent=why) if why else frag


GROUND_SPEED_TOLERANCE_M_S = 0.005
"""How far NAV-PVT's gSpeed may lie from the norm of its velN and velE: the receiver
computes it from them, each rounded to 1 mm/s."""


def _nav_pvt_inconsistency(frag: Fragment) -> str:
    """Why a NAV-PVT whose checksum passed cannot be what the receiver sent, or ''.

    UBX's checksum is an 8-bit Fletcher: two flips of bit 7 in bytes of the same parity
    (or one in the payload and the matching ones in CK_A and CK_B) leave it unchanged. On a
    noisy line (1 % of the bytes hit, the soak) that let about one NAV-PVT an hour through
    with velE 32.8 m/s off (issue 26). The frame says its horizontal speed twice, gSpeed
    and velN, velE: a byte hit in any of them shows."""
    velocity = frag.velocity_ned_m_s
    if velocity is None or frag.ground_speed_m_s is None:
        return ""
    speed = math.hypot(velocity[0], velocity[1])
    if abs(speed - frag.ground_speed_m_s) > GROUND_SPEED_TOLERANCE_M_S:
        return (f"gSpeed {frag.ground_speed_m_s:.3f} m/s but velN, velE make "
                f"{speed:.3f} m/s")
    return ""


def _nav_pvt(msg: Any, ident: str) -> Fragment:
    fix = FixType(int(msg.fixType)) if int(msg.fixType) in range(6) else FixType.NO_FIX
    fix_ok = bool(int(msg.gnssFixOk))
    frag = Fragment(
        kind=ident,
        gps_time_of_week_s=int(msg.iTOW) / 1000.0,
        time_of_day_s=(int(msg.hour) * 3600 + int(msg.min) * 60 + int(msg.second)
                       + int(msg.nano) * 1e-9),
        day=date(int(msg.year), int(msg.month), int(msg.day)) if int(msg.month) else None,
        fix_type=fix if fix_ok else FixType.NO_FIX,
        satellites=int(msg.numSV),
        horizontal_accuracy_m=int(msg.hAcc) / 1000.0,
        vertical_accuracy_m=int(msg.vAcc) / 1000.0,
        speed_accuracy_m_s=int(msg.sAcc) / 1000.0,
    )
    # pyubx2 applies the 1e-7 deg scale to lat/lon; heights and velocities are mm, mm/s.
    frag.latitude_deg = float(msg.lat)
    frag.longitude_deg = float(msg.lon)
    frag.height_msl_m = int(msg.hMSL) / 1000.0
    frag.height_ellipsoid_m = int(msg.height) / 1000.0
    frag.velocity_ned_m_s = (int(msg.velN) / 1000.0, int(msg.velE) / 1000.0,
                             int(msg.velD) / 1000.0)
    frag.ground_speed_m_s = int(msg.gSpeed) / 1000.0
    frag.course_deg = float(msg.headMot)
    return frag
