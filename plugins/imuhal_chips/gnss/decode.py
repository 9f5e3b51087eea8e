"""Decoding what a receiver sends: NMEA through pynmea2, UBX NAV-PVT through pyubx2.

Pure functions from one sentence or frame to a :class:`Epoch` fragment in SI units. A bad
checksum is reported as such (``checksum_ok=False``) with whatever could still be read, so
the driver can flag and count it; it is never merged into a fix.
"""

from __future__ import annotations

import math
import struct
from dataclasses import dataclass, field
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
    time_valid: bool | None = None
    """NAV-PVT's validity flags: the receiver says its UTC date and time of day are valid
    and fully resolved (validDate, validTime, fullyResolved); None: not stated (NMEA)."""
    acked: tuple[int, int] | None = None
    """ACK-ACK / ACK-NAK: the (class, id) of the acknowledged message."""
    inconsistent: str = ""
    """Why a frame whose checksum passed still failed its integrity check (then
    ``checksum_ok`` is False and nothing else is read); empty when it did not."""
    rounding: dict[str, float] = field(default_factory=dict)
    """Per field name (``latitude_deg``, ``ground_speed_m_s``, ...): how far the value an
    NMEA sentence printed can lie from the receiver's own by its rounding, half a unit of
    its last printed digit, in the field's unit."""


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
    except (ValueError, TypeError, AttributeError, KeyError) as exc:
        raise DecodeError(f"{kind}: {exc}") from exc
    if frag.inconsistent and checksum_ok:
        return Fragment(kind=kind, checksum_ok=False, inconsistent=frag.inconsistent)
    return frag


def _half_unit(text: str) -> float:
    """Half a unit of the last digit printed in ``text`` (how far its rounding can be off)."""
    return 0.5 * 10.0 ** -len(text.partition(".")[2])


def _raw(msg: Any, name: str) -> str:
    """The text of a pynmea2 sentence's field ``name``, as the receiver printed it."""
    index = msg.name_to_idx[name]
    return str(msg.data[index]) if index < len(msg.data) else ""


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
            _position_rounding(frag, msg)
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
            _position_rounding(frag, msg)
            _velocity(frag, _raw(msg, "spd_over_grnd"), _raw(msg, "true_course"))
    elif kind == "VTG":
        _velocity(frag, _raw(msg, "spd_over_grnd_kts"), _raw(msg, "true_track"))
        frag.inconsistent = _vtg_inconsistency(frag, _raw(msg, "spd_over_grnd_kmph"))
    elif kind == "GSA":
        mode = int(msg.mode_fix_type or 1)
        frag.fix_type = {1: FixType.NO_FIX, 2: FixType.FIX_2D, 3: FixType.FIX_3D}.get(
            mode, FixType.NO_FIX)
        frag.hdop = _f(msg.hdop)


def _position_rounding(frag: Fragment, msg: Any) -> None:
    """Latitude and longitude are printed in minutes (ddmm.mmmm)."""
    frag.rounding["latitude_deg"] = _half_unit(_raw(msg, "lat")) / 60.0
    frag.rounding["longitude_deg"] = _half_unit(_raw(msg, "lon")) / 60.0


def _velocity(frag: Fragment, knots: str, course: str) -> None:
    """Ground speed (printed in knots) and course over ground (deg) of RMC or VTG."""
    speed = _f(knots)
    frag.ground_speed_m_s = None if speed is None else speed * KNOT_M_S
    frag.course_deg = _f(course)
    if speed is not None:
        frag.rounding["ground_speed_m_s"] = _half_unit(knots) * KNOT_M_S
    if frag.course_deg is not None:
        frag.rounding["course_deg"] = _half_unit(course)


def _vtg_inconsistency(frag: Fragment, kmph: str) -> str:
    """Why a VTG's two speeds (knots and km/h, the same speed printed twice) disagree by
    more than their rounding, or ''."""
    speed_kmph = _f(kmph)
    if frag.ground_speed_m_s is None or speed_kmph is None:
        return ""
    allowed = frag.rounding["ground_speed_m_s"] + _half_unit(kmph) / 3.6 + 1e-9
    if abs(speed_kmph / 3.6 - frag.ground_speed_m_s) > allowed:
        return (f"VTG says {frag.ground_speed_m_s:.3f} m/s in knots but "
                f"{speed_kmph / 3.6:.3f} m/s in km/h")
    return ""


NMEA_REPEATED = ("latitude_deg", "longitude_deg", "ground_speed_m_s", "course_deg")
"""What the sentences of one NMEA epoch say more than once: the position (RMC and GGA), the
ground speed and course (RMC and VTG)."""


def sentences_disagree(parts: list[Fragment]) -> str:
    """Why the sentences of one epoch cannot all be what the receiver sent, or ''.

    NMEA's 8-bit XOR checksum misses the same bit flipped in two characters of a sentence
    (or one character and the matching bit of a checksum digit): a digit moved by 1, 2, 4
    or 8 in its place. The receiver prints one solution in each sentence, so what two of
    them both say must agree to their rounding (half a unit of each one's last digit)."""
    said: dict[str, Fragment] = {}
    for part in parts:
        for name in NMEA_REPEATED:
            value = getattr(part, name)
            if value is None or name not in part.rounding:
                continue
            first = said.setdefault(name, part)
            if first is part:
                continue
            difference = value - getattr(first, name)
            if name == "course_deg":
                difference = (difference + 180.0) % 360.0 - 180.0
            if abs(difference) > first.rounding[name] + part.rounding[name] + 1e-9:
                return (f"{first.kind} and {part.kind} disagree on {name}: "
                        f"{getattr(first, name):.7g} and {value:.7g}")
    return ""


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
        time_valid=bool(int(msg.validDate) and int(msg.validTime)
                        and int(msg.fullyResolved)),
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
