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
