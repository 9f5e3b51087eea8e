"""Hostile input files for every format the CLI reads (issue 26 item 5): hypothesis
strategies shared by the suite's fuzz tests (tests/cli/test_fuzz_inputs.py, a few dozen
cases per format) and the on-demand 2,000-cases-per-format run
(tests/benchmarks/fuzz_inputs.py).

Each case is a file built from a good one by the mistakes a cut, a flipped bit, a crafted
file or a careless edit make, fed to the command that reads it in-process. The verdict:
exit 0, or exit 2 with exactly one ``imuhal: error:`` line; anything else (exit 70, a
traceback, a hang the time bound catches) fails.
"""

from __future__ import annotations

import contextlib
import io
import json
import signal
import struct
import zlib
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import yaml
from hypothesis import strategies as st

from imuhal.cli import main as cli_main

RECORDING_PREFIX = 10
"""Magic (8 bytes) and format version (u16) before the first chunk."""

IMU_COLUMNS = ("t_s", "gx_rad_s", "gy_rad_s", "gz_rad_s", "ax_m_s2", "ay_m_s2", "az_m_s2",
               "mx_ut", "my_ut", "mz_ut", "pressure_pa")


@dataclass(frozen=True)
class Outcome:
    exit_code: int
    stderr: str
    stdout: str = ""

    @property
    def clean(self) -> bool:
        """Exit 0, or exit 2 with one ``imuhal: error:`` line and no traceback."""
        if "Traceback" in self.stderr or "internal error" in self.stderr:
            return False
        errors = [line for line in self.stderr.splitlines()
                  if line.startswith("imuhal") and ": error:" in line]
        if self.exit_code == 0:
            return True
        return self.exit_code == 2 and len(errors) == 1


CASE_TIME_LIMIT_S = 20.0
"""A case that has used this much CPU time is a hang (a spinning loop): it fails (SIGPROF)."""

CASE_WALL_LIMIT_S = 120.0
"""A case still running after this long on the wall clock is a hang (a blocked wait): it fails
(SIGALRM). Far above the CPU bound because a loaded machine stretches honest cases' wall time."""


class Hang(Exception):
    pass


@contextlib.contextmanager
def time_limit(cpu_seconds: float, wall_seconds: float | None = None) -> Iterator[None]:
    """Raise `Hang` inside the block once it has used `cpu_seconds` of process CPU time or
    `wall_seconds` (default 6x the CPU bound) of wall time: CPU time keeps the bound honest on
    a busy machine, the wall bound still catches a case that blocks forever."""
    wall = 6.0 * cpu_seconds if wall_seconds is None else wall_seconds

    def expire(_signum: int, _frame: object) -> None:
        raise Hang(f"still running after {cpu_seconds:g} s of CPU or {wall:g} s of wall time")
    previous_prof = signal.signal(signal.SIGPROF, expire)
    previous_alrm = signal.signal(signal.SIGALRM, expire)
    signal.setitimer(signal.ITIMER_PROF, cpu_seconds)
    signal.setitimer(signal.ITIMER_REAL, wall)
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_PROF, 0)
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGPROF, previous_prof)
        signal.signal(signal.SIGALRM, previous_alrm)


def run_cli(argv: Sequence[str]) -> Outcome:
    """``imuhal ARGV`` in this process: its exit code and what it printed on stderr (a hang
    past CASE_TIME_LIMIT_S of CPU or CASE_WALL_LIMIT_S of wall time comes back as exit 124)."""
    err, out = io.StringIO(), io.StringIO()
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(out):
        try:
            with time_limit(CASE_TIME_LIMIT_S, CASE_WALL_LIMIT_S):
                code = cli_main.main(list(argv))
        except SystemExit as exc:  # argparse
            code = exc.code if isinstance(exc.code, int) else 2
        except Hang as exc:
            print(f"hang: {exc}", file=err)
            code = 124
    return Outcome(int(code), err.getvalue(), out.getvalue())


# -- recordings ----------------------------------------------------------------------------

def recording_chunks(data: bytes) -> list[bytes]:
    """The payloads of a well-formed recording's chunks (header first)."""
    pos, out = RECORDING_PREFIX, []
    while pos < len(data):
        length, _crc = struct.unpack_from("<II", data, pos)
        out.append(data[pos + 8:pos + 8 + length])
        pos += 8 + length
    return out


def recording_of(prefix: bytes, chunks: Sequence[bytes]) -> bytes:
    """A recording of these chunk payloads, each with its correct CRC."""
    return prefix + b"".join(struct.pack("<II", len(c), zlib.crc32(c)) + c for c in chunks)


@st.composite
def damaged_recordings(draw: st.DrawFn, good: bytes) -> bytes:
    """A cut, bit flips, garbled records under a correct CRC, or a crafted header."""
    chunks = recording_chunks(good)
    how = draw(st.sampled_from(["cut", "flip", "garble", "header"]))
    if how == "cut":
        return good[:draw(st.integers(0, len(good)))]
    if how == "flip":
        data = bytearray(good)
        for at in draw(st.lists(st.integers(0, len(good) - 1), min_size=1, max_size=6)):
            data[at] ^= 1 << draw(st.integers(0, 7))
        return bytes(data)
    if how == "garble":
        index = draw(st.integers(1, len(chunks) - 1))
        chunk = bytearray(chunks[index])
        for at in draw(st.lists(st.integers(0, len(chunk) - 1), min_size=1, max_size=10)):
            chunk[at] = draw(st.integers(0, 255))
        return recording_of(good[:RECORDING_PREFIX],
                            [*chunks[:index], bytes(chunk), *chunks[index + 1:]])
    header = draw(st.one_of(
        st.binary(max_size=64),
        st.recursive(st.none() | st.booleans() | st.integers() | st.text(max_size=20),
                     lambda inner: st.lists(inner, max_size=3)
                     | st.dictionaries(st.text(max_size=10), inner, max_size=3),
                     max_leaves=10).map(lambda v: json.dumps(v).encode()),
    ))
    return recording_of(good[:RECORDING_PREFIX], [header, *chunks[1:]])


# -- CSV -----------------------------------------------------------------------------------

_CELLS = st.one_of(
    st.floats(allow_nan=True, allow_infinity=True).map(repr),
    st.sampled_from(["", "inf", "-inf", "nan", "1e300", "-1e300", "1e-320", "0x10", "1_0",
                     "  1", "\u0661", "true", "None", '"', '""', "1,5", "\x00"]),
    st.text(max_size=12),
    st.integers(1, 3).map(lambda n: "9" * (131_072 * n + 1)),
)


@st.composite
def hostile_csv(draw: st.DrawFn, columns: Sequence[str] = IMU_COLUMNS) -> bytes:
    """A CSV of samples or truth: a plausible header (columns dropped, repeated, renamed),
    then rows of hostile cells, sometimes not UTF-8 or without a trailing newline."""
    header = list(draw(st.lists(st.sampled_from(list(columns)), min_size=1,
                                max_size=len(columns) + 2)))
    if draw(st.booleans()):
        header = list(columns)
    if draw(st.integers(0, 9)) == 0:
        header.append(draw(st.text(max_size=8)))
    rows = draw(st.lists(st.lists(_CELLS, min_size=len(header) - 1,
                                  max_size=len(header) + 1), max_size=8))
    text = ",".join(header) + "\n" + "".join(",".join(row) + "\n" for row in rows)
    data = text.encode("utf-8", "surrogatepass")
    if draw(st.integers(0, 9)) == 0:
        data += draw(st.binary(min_size=1, max_size=16))
    return data


# -- profiles ------------------------------------------------------------------------------

_YAML_LEAVES = st.one_of(
    st.none(), st.booleans(), st.integers(-2**70, 2**70),
    st.floats(allow_nan=True, allow_infinity=True), st.text(max_size=12),
    st.sampled_from(["!!binary AAAA", "!!timestamp 2001-12-14", "!!set {a, b}", "*nosuch",
                     "&a [*a]", "? {k: 1}\n: 2", "0x76", "1e400", "-1", "~", ".nan"]),
)


def _mutate(value: Any, path: Sequence[Any], new: Any) -> Any:
    if not path:
        return new
    head, rest = path[0], path[1:]
    if isinstance(value, dict) and head in value:
        return {**value, head: _mutate(value[head], rest, new)}
    if isinstance(value, list) and isinstance(head, int) and head < len(value):
        return [*value[:head], _mutate(value[head], rest, new), *value[head + 1:]]
    return value


def _paths(value: Any, prefix: tuple[Any, ...] = ()) -> list[tuple[Any, ...]]:
    out = [prefix]
    if isinstance(value, dict):
        for k, v in value.items():
            out += _paths(v, (*prefix, k))
    elif isinstance(value, list):
        for i, v in enumerate(value):
            out += _paths(v, (*prefix, i))
    return out


@st.composite
def hostile_profiles(draw: st.DrawFn, good_text: str) -> str:
    """A good profile with one value replaced (by a leaf, a raw YAML fragment, a deep or a
    wide structure), or its text cut or spliced."""
    good = yaml.safe_load(good_text)
    how = draw(st.sampled_from(["value", "raw", "deep", "text"]))
    if how == "text":
        cut = draw(st.integers(0, len(good_text)))
        return good_text[:cut] + draw(st.text(max_size=20)) + good_text[cut:][
            draw(st.integers(0, 40)):]
    path = draw(st.sampled_from(_paths(good)))
    if how == "deep":
        depth = draw(st.integers(20, 600))
        return yaml.safe_dump(_mutate(good, path, "PLACEHOLDER")).replace(
            "PLACEHOLDER", "[" * depth + "]" * depth, 1)
    if how == "raw":
        fragment = draw(_YAML_LEAVES.filter(lambda v: isinstance(v, str)))
        marker = "RAWFRAGMENT"
        text = yaml.safe_dump(_mutate(good, path, marker))
        # a raw fragment as the value, flow-style so that it stays on its line
        return text.replace(f"'{marker}'", marker).replace(marker, fragment.replace("\n", " "))
    new = draw(st.recursive(_YAML_LEAVES, lambda inner: st.lists(inner, max_size=3)
                            | st.dictionaries(st.text(max_size=8) | st.integers(), inner,
                                              max_size=3), max_leaves=8))
    return yaml.safe_dump(_mutate(good, path, new), allow_unicode=True)


# -- NMEA and UBX ----------------------------------------------------------------------------

def nmea_sentence(body: str) -> bytes:
    """``$BODY*CS\\r\\n`` with a correct checksum."""
    checksum = 0
    for ch in body.encode("ascii", "replace"):
        checksum ^= ch
    return f"${body}*{checksum:02X}\r\n".encode("ascii", "replace")


def ubx_frame(msg_class: int, msg_id: int, payload: bytes) -> bytes:
    """A UBX frame with a correct checksum."""
    body = bytes([msg_class, msg_id]) + struct.pack("<H", len(payload)) + payload
    ck_a = ck_b = 0
    for b in body:
        ck_a = (ck_a + b) & 0xFF
        ck_b = (ck_b + ck_a) & 0xFF
    return b"\xb5\x62" + body + bytes([ck_a, ck_b])


_NMEA_FIELD = st.one_of(st.sampled_from(["", "0", "1", "A", "V", "N", "S", "E", "W", "M",
                                         "123519", "999999", "4807.038", "01131.000",
                                         "9999.99", "-1", "nan", "inf", "1e999", "230394",
                                         "320299", "x"]),
                        st.text(alphabet=st.characters(min_codepoint=32, max_codepoint=126,
                                                       exclude_characters="$*\r\n"),
                                max_size=10))


@st.composite
def gnss_streams(draw: st.DrawFn) -> list[bytes]:
    """What a receiver's UART delivers, read in chunks: NMEA sentences and UBX frames with
    correct checksums but hostile fields, corrupted ones, and noise."""
    items: list[bytes] = []
    for _ in range(draw(st.integers(1, 12))):
        kind = draw(st.sampled_from(["nmea", "pvt", "ubx", "noise"]))
        if kind == "nmea":
            talker = draw(st.sampled_from(["GP", "GN", "GL", "P"]))
            name = draw(st.sampled_from(["GGA", "RMC", "VTG", "GSA", "GSV", "ZDA", "XYZ"]))
            fields = draw(st.lists(_NMEA_FIELD, max_size=16))
            items.append(nmea_sentence(talker + name + "," + ",".join(fields)))
        elif kind == "pvt":
            items.append(ubx_frame(0x01, 0x07, draw(st.binary(min_size=92, max_size=92))))
        elif kind == "ubx":
            items.append(ubx_frame(draw(st.sampled_from([0x01, 0x05, 0x06, 0x0A])),
                                   draw(st.integers(0, 255)), draw(st.binary(max_size=40))))
        else:
            items.append(draw(st.binary(max_size=40)))
    stream = b"".join(items)
    if stream and draw(st.booleans()):
        flipped = bytearray(stream)
        flipped[draw(st.integers(0, len(stream) - 1))] ^= 1 << draw(st.integers(0, 7))
        stream = bytes(flipped)
    cuts = sorted(draw(st.lists(st.integers(0, len(stream)), max_size=6)))
    return [stream[a:b] for a, b in zip([0, *cuts], [*cuts, len(stream)], strict=True)]


def write(path: Path, data: bytes | str) -> Path:
    if isinstance(data, str):
        path.write_text(data, encoding="utf-8", errors="surrogatepass")
    else:
        path.write_bytes(data)
    return path

