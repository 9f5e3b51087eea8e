"""A minimal, strict IGC reader written from the FAI's "Technical specification for IGC-
approved GNSS flight recorders" (appendix A, the file format), independent of the library
imuhal writes with (aerofiles): every line ends in CR LF and holds at most 76 characters,
the A record comes first, the B record is ``B HHMMSS DDMMmmm N|S DDDMMmmm E|W A|V PPPPP
GGGGG`` (35 bytes) followed by the extensions the I record declares, byte positions counted
from 1. Anything else fails with ValueError naming the line."""

from __future__ import annotations

import re
from dataclasses import dataclass, field

B_RECORD = re.compile(
    r"B(\d{2})(\d{2})(\d{2})(\d{2})(\d{5})([NS])(\d{3})(\d{5})([EW])([AV])"
    r"([-\d]\d{4})([-\d]\d{4})")
I_RECORD = re.compile(r"I(\d{2})((?:\d{4}[A-Z0-9]{3})*)")


@dataclass
class Fix:
    seconds_of_day: int
    latitude_deg: float
    longitude_deg: float
    valid: bool
    pressure_altitude_m: int
    gnss_altitude_m: int
    extensions: dict[str, str]


@dataclass
class IgcFile:
    a_record: str
    headers: dict[str, str] = field(default_factory=dict)
    fixes: list[Fix] = field(default_factory=list)
    comments: list[str] = field(default_factory=list)
    g_records: list[str] = field(default_factory=list)


Extension = tuple[int, int, str]  # first byte, last byte (1-based), three-letter code


def _parse_h(n: int, line: str, out: IgcFile) -> None:
    m = re.fullmatch(r"H([FOP])([A-Z0-9]{3})(.*)", line)
    if m is None:
        raise ValueError(f"line {n}: malformed H record")
    out.headers[m.group(2)] = m.group(3).split(":", 1)[-1]


def _parse_i(n: int, line: str) -> list[Extension]:
    """The B-record extensions the I record declares, contiguous from byte 36."""
    m = I_RECORD.fullmatch(line)
    if m is None or int(m.group(1)) * 7 != len(m.group(2)):
        raise ValueError(f"line {n}: malformed I record")
    body = m.group(2)
    extensions: list[Extension] = []
    expected_start = 36
    for k in range(int(m.group(1))):
        field7 = body[7 * k:7 * k + 7]
        start, end, code = int(field7[0:2]), int(field7[2:4]), field7[4:7]
        if start != expected_start or end < start:
            raise ValueError(f"line {n}: extension {code} at bytes {start}-{end}")
        extensions.append((start, end, code))
        expected_start = end + 1
    return extensions


def _parse_b(n: int, line: str, extensions: list[Extension]) -> Fix:
    length = extensions[-1][1] if extensions else 35
    m = B_RECORD.match(line)
    if m is None or len(line) != length:
        raise ValueError(f"line {n}: malformed B record {line!r} (length {length})")
    g = m.groups()
    hh, mm, ss = int(g[0]), int(g[1]), int(g[2])
    lat_min = int(g[4]) / 1000.0
    lon_min = int(g[7]) / 1000.0
    if hh > 23 or mm > 59 or ss > 59 or lat_min >= 60 or lon_min >= 60:
        raise ValueError(f"line {n}: time or minutes out of range")
    lat = (int(g[3]) + lat_min / 60.0) * (1 if g[5] == "N" else -1)
    lon = (int(g[6]) + lon_min / 60.0) * (1 if g[8] == "E" else -1)
    ext = {code: line[s - 1:e] for s, e, code in extensions}
    return Fix(hh * 3600 + mm * 60 + ss, lat, lon, g[9] == "A", int(g[10]), int(g[11]), ext)


def _lines(data: bytes) -> list[str]:
    text = data.decode("ascii")
    if not text.endswith("\r\n"):
        raise ValueError("the file does not end with CR LF")
    lines = text[:-2].split("\r\n")
    if not lines[0].startswith("A") or len(lines[0]) < 4:
        raise ValueError("line 1: no A record")
    return lines


def parse_igc(data: bytes) -> IgcFile:
    lines = _lines(data)
    out = IgcFile(a_record=lines[0])
    extensions: list[Extension] = []
    for n, line in enumerate(lines[1:], 2):
        if "\r" in line or "\n" in line or len(line) > 76 or not line:
            raise ValueError(f"line {n}: not a record (bare CR/LF, empty, or > 76 chars)")
        kind = line[0]
        if out.g_records and kind != "G":
            raise ValueError(f"line {n}: {kind} record after the G record")
        if kind == "H":
            _parse_h(n, line, out)
        elif kind == "I":
            extensions = _parse_i(n, line)
        elif kind == "B":
            out.fixes.append(_parse_b(n, line, extensions))
        elif kind == "L":
            out.comments.append(line[1:])
        elif kind == "G":
            out.g_records.append(line[1:])
        elif kind not in "CDEFJK":
            raise ValueError(f"line {n}: unknown record type {kind!r}")
    if "DTE" not in out.headers:
        raise ValueError("no HFDTE (date) header")
    return out
