"""An independent NMEA reader for tests: checksum by hand, fields split by hand."""

from __future__ import annotations


def read_sentence(line: str) -> tuple[str, list[str]]:
    """(talker+type, fields) of one ``$...*CS`` sentence; AssertionError if the checksum is
    wrong. FlyNet's ``_PRS`` (no checksum) comes back as ("_PRS", [hex])."""
    line = line.strip()
    if line.startswith("_PRS "):
        return "_PRS", [line[5:]]
    assert line.startswith("$") and line[-3] == "*", line
    body, cs = line[1:-3], line[-2:]
    x = 0
    for ch in body:
        x ^= ord(ch)
    assert f"{x:02X}" == cs, f"checksum of {line!r}: {x:02X}"
    head, *fields = body.split(",")
    return head, fields


def read_lxwp0(line: str) -> dict[str, float | str | None]:
    """The published LXWP0 layout (LX Navigation's data port; XCSoar Driver/LX/Parser.cpp):
    12 fields after the type, exactly; empty = not given."""
    head, f = read_sentence(line)
    assert head == "LXWP0" and len(f) == 12, line
    assert f[0] in ("Y", "N")
    names = ("tas_km_h", "pressure_altitude_m", "vario_m_s", "vario2", "vario3", "vario4",
             "vario5", "vario6", "heading_deg", "wind_from_deg", "wind_km_h")
    out: dict[str, float | str | None] = {"logger": f[0]}
    for name, text in zip(names, f[1:], strict=True):
        out[name] = float(text) if text else None
    return out
