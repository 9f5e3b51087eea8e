"""Reading sample CSVs strictly: every bad cell is an error naming its row and column.

Header names carry units and frames (project convention): ``t_s``; gyro ``gx_rad_s`` ...;
accelerometer specific force ``ax_m_s2`` ... in NED body axes (level at rest: az = -9.81);
magnetometer ``mx_ut`` ...; ``pressure_pa``; for the vario filters also ``altitude_m`` and
``accel_up_m_s2`` (gravity-compensated vertical acceleration, up positive).

Sensors at different rates share one file: a slower sensor's cells are empty on the rows
where it had no sample (magnetometer, pressure, and in the vertical form both altitude and
acceleration), so each row carries what was measured at its time.
"""

from __future__ import annotations

import csv
import math
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import BinaryIO

import numpy as np

from imuhal.core.errors import ImuhalError
from imuhal.offline.fast_csv import parse_block

TIME = "t_s"
GYRO = ("gx_rad_s", "gy_rad_s", "gz_rad_s")
ACCEL = ("ax_m_s2", "ay_m_s2", "az_m_s2")
MAG = ("mx_ut", "my_ut", "mz_ut")
PRESSURE = "pressure_pa"
ALTITUDE = "altitude_m"
ACCEL_UP = "accel_up_m_s2"

MAX_TIME_S = 1e9
"""Largest |t_s| accepted (31 years): times become integer nanoseconds, which must fit 64 bits."""

SPARSE_COLUMNS = frozenset({PRESSURE, *MAG, ALTITUDE, ACCEL_UP})
"""Columns whose cells may be empty: a slower sensor has no sample on that row."""


class InputError(ImuhalError):
    """The input CSV cannot be used; the message names the row and column."""


@dataclass
class SampleTable:
    path: Path
    columns: dict[str, np.ndarray]
    """Column name -> float array (NaN marks an empty cell of a sparse column)."""
    lines: np.ndarray
    """The file line number of each data row (header is line 1)."""

    def __len__(self) -> int:
        return len(self.lines)

    def has(self, *names: str) -> bool:
        return all(n in self.columns for n in names)


CHUNK_ROWS = 8_192
"""Rows per chunk of :func:`iter_sample_chunks`: memory stays flat in the length of the log."""


def read_sample_csv(path: str | Path, *, rate_hz: float | None = None) -> SampleTable:
    """Read and check a whole sample CSV into memory (small files, tests; ``imuhal
    estimate`` streams with :func:`iter_sample_chunks`). Without a ``t_s`` column,
    ``rate_hz`` gives the times."""
    chunks = list(iter_sample_chunks(path, rate_hz=rate_hz))
    first = chunks[0]
    if len(chunks) == 1:
        return first
    columns = {name: np.concatenate([c.columns[name] for c in chunks]) for name in first.columns}
    return SampleTable(first.path, columns, np.concatenate([c.lines for c in chunks]))


def _read_header(p: Path, line: bytes, rate_hz: float | None) -> list[str]:
    """The checked header line: comma-separated, each name once, and a time column unless
    ``rate_hz`` gives the times (never both)."""
    if not line:
        raise InputError(f"{p}: the file is empty; expected a header line")
    try:
        # utf-8-sig: a byte-order mark (spreadsheets write one) is not part of the first name
        header = [h.strip() for h in next(csv.reader([line.decode("utf-8-sig")]))]
    except (UnicodeDecodeError, csv.Error, StopIteration) as exc:
        raise InputError(f"{p}: not a CSV text file ({exc})") from None
    if len(header) == 1:
        for sep, name in ((";", "semicolons"), ("\t", "tabs"), ("|", "bars")):
            if sep in header[0]:
                raise InputError(f"{p}: line 1: the columns are separated by {name}; imuhal "
                                 "reads comma-separated values: save the file with ',' as "
                                 "the delimiter")
    dupes = {h for h in header if header.count(h) > 1}
    if dupes:
        raise InputError(f"{p}: line 1: duplicate column(s) {', '.join(sorted(dupes))}")
    if TIME not in header and rate_hz is None:
        raise InputError(f"{p}: missing column '{TIME}' (seconds); add it or give --rate HZ")
    if TIME in header and rate_hz is not None:
        raise InputError(f"{p}: has a '{TIME}' column, which gives the times; --rate is "
                         "for input without one - drop --rate")
    return header


def iter_sample_chunks(path: str | Path, *, rate_hz: float | None = None,
                       chunk_rows: int | None = None) -> Iterator[SampleTable]:
    """Read and check a sample CSV in tables of at most ``chunk_rows`` rows, in file order.

    The checks are those of the whole file (every bad cell an :class:`InputError` naming its
    line and column; times increasing across chunks too), but only one chunk is in memory.
    At least one chunk is yielded (a file without data rows is an error). ``chunk_rows``
    defaults to :data:`CHUNK_ROWS`. A chunk of plain numbers is parsed whole
    (:func:`imuhal.offline.fast_csv.parse_block`); any other is read cell by cell.
    """
    chunk_rows = chunk_rows or CHUNK_ROWS
    p = Path(path)
    try:
        handle = p.open("rb")
    except OSError as exc:
        raise InputError(f"{p}: cannot read: {exc.strerror or exc}") from None
    with handle:
        header = _read_header(p, handle.readline(), rate_hz)
        sparse = [_sparse(n) for n in header]
        # a blank row would pass as empty cells where every column may be empty: cell by cell
        whole = not all(sparse)
        done = 0
        next_line = 2
        last_t: float | None = None
        for lines, count in _line_blocks(handle, chunk_rows):
            values = parse_block(lines, count, len(header), sparse) if whole else None
            if values is not None:
                line_arr = np.arange(next_line, next_line + count)
                columns = {name: values[:, i] for i, name in enumerate(header)}
            else:
                rows, line_list = _strict_rows(p, lines.splitlines(keepends=True), next_line,
                                               len(header))
                columns, line_arr = _strict_columns(p, header, rows, line_list)
            next_line += count
            if not len(line_arr):
                continue
            table = _table(p, columns, line_arr, done, rate_hz, last_t)
            yield table
            done += len(table)
            last_t = float(table.columns[TIME][-1])
    if not done:
        raise InputError(f"{p}: no data rows after the header")


def _line_blocks(handle: BinaryIO, rows: int) -> Iterator[tuple[bytes, int]]:
    """The rest of ``handle`` as blocks of ``rows`` whole lines (fewer in the last), each
    ending in a newline (one is added to a last line without), with their line counts. Read
    in large reads, the lines found with numpy: no Python object per line."""
    block = max(rows * 128, 1 << 16)
    rest = b""
    while True:
        more = handle.read(block)
        data = rest + more
        if not more:
            if data:
                data = data if data.endswith(b"\n") else data + b"\n"
                yield data, data.count(b"\n")
            return
        ends = np.flatnonzero(np.frombuffer(data, dtype=np.uint8) == _NEWLINE)
        start = 0
        for k in range(rows, len(ends) + 1, rows):
            stop = int(ends[k - 1]) + 1
            yield data[start:stop], rows
            start = stop
        rest = data[start:]
        # about one block of rows per read from now on
        if len(ends):
            block = max(int(ends[-1] + 1) * rows // len(ends), 1 << 12)


_NEWLINE = ord("\n")


def _strict_rows(p: Path, lines: list[bytes], first_line: int, width: int
                 ) -> tuple[list[list[str]], list[int]]:
    """(cells, line number) of each row of ``lines`` (file lines from ``first_line`` on)
    read by the csv module; blank rows are skipped, a row of another width is an error."""
    text: list[str] = []
    for i, line in enumerate(lines):
        try:
            text.append(line.decode("utf-8"))
        except UnicodeDecodeError as exc:
            raise InputError(f"{p}: line {first_line + i}: not CSV text ({exc})") from None
    reader = csv.reader(text)
    rows: list[list[str]] = []
    numbers: list[int] = []
    while True:
        try:
            cells = next(reader)
        except StopIteration:
            return rows, numbers
        except csv.Error as exc:
            raise InputError(f"{p}: line {first_line + reader.line_num - 1}: not CSV text "
                             f"({exc})") from None
        line_no = first_line + reader.line_num - 1
        if len(cells) != width:
            if not cells or all(not c.strip() for c in cells):
                continue
            raise InputError(f"{p}: line {line_no}: {len(cells)} cells, but the header has "
                             f"{width} columns")
        rows.append(cells)
        numbers.append(line_no)


def _sparse(column: str) -> bool:
    # a frame suffix (mx_ut_enu, see offline/frames.py) keeps the column sparse
    return column in SPARSE_COLUMNS or column.rsplit("_", 1)[0] in SPARSE_COLUMNS


def _strict_columns(path: Path, header: list[str], rows: list[list[str]], lines: list[int]
                    ) -> tuple[dict[str, np.ndarray], np.ndarray]:
    """Rows of cells as columns: whole columns at C speed where every cell is a plain
    number, else the strict cell-by-cell reading (blank rows skipped, a one-line error per
    bad cell)."""
    if all(_sparse(n) for n in header):  # no required column would catch a blank row
        rows, lines = _drop_blank(rows, lines)
    columns: dict[str, np.ndarray] = {}
    fast = True
    for name, cells in zip(header, zip(*rows, strict=True), strict=False):
        values = _fast_column(name, cells)
        if values is None:
            fast = False
            break
        columns[name] = values
    if not fast:
        rows, lines = _drop_blank(rows, lines)
        strict = [[_cell(path, n, name, c) for name, c in zip(header, r, strict=True)]
                  for r, n in zip(rows, lines, strict=True)]
        data = np.array(strict, dtype=float).reshape(len(rows), len(header))
        columns = {name: data[:, i] for i, name in enumerate(header)}
    return columns, np.array(lines, dtype=np.int64)


def _table(path: Path, columns: dict[str, np.ndarray], lines: np.ndarray, start: int,
           rate_hz: float | None, last_t: float | None) -> SampleTable:
    """The chunk's table: times from ``rate_hz`` when the file has none, checked to increase
    (also from ``last_t``, the previous chunk's last time)."""
    if TIME not in columns:
        assert rate_hz is not None
        columns[TIME] = (start + np.arange(len(lines))) / rate_hz
    t = columns[TIME]
    if last_t is not None:
        _check_time(path, np.concatenate([[last_t], t]), np.concatenate([lines[:1], lines]))
    else:
        _check_time(path, t, lines)
    return SampleTable(path, columns, lines)


def _fast_column(name: str, cells: tuple[str, ...]) -> np.ndarray | None:
    """The column's values when every cell is a finite number (or, in a sparse column,
    empty); None when any cell needs the strict reading."""
    try:
        if _sparse(name):
            values = np.array([float(c) if c else math.nan for c in cells])
            ok = np.isfinite(values) | np.array([not c for c in cells], dtype=bool)
        else:
            values = np.array(list(map(float, cells)))
            ok = np.isfinite(values)
    except ValueError:
        return None
    return values if bool(ok.all()) else None


def _drop_blank(rows: list[list[str]], lines: list[int]) -> tuple[list[list[str]], list[int]]:
    keep = [i for i, r in enumerate(rows) if any(c.strip() for c in r)]
    return [rows[i] for i in keep], [lines[i] for i in keep]


def _cell(path: Path, line_no: int, column: str, cell: str) -> float:
    text = cell.strip()
    if not text:
        if _sparse(column):
            return math.nan
        raise InputError(f"{path}: line {line_no}, column '{column}': empty cell")
    try:
        value = float(text)
    except ValueError:
        raise InputError(f"{path}: line {line_no}, column '{column}': {text!r} is not a "
                         "number") from None
    if not math.isfinite(value):
        raise InputError(f"{path}: line {line_no}, column '{column}': {text!r} is not a finite "
                         "number (NaN and inf are not accepted; leave a sparse cell empty)")
    return value


def _check_time(path: Path, t: np.ndarray, lines: np.ndarray) -> None:
    far = np.flatnonzero(np.abs(t) > MAX_TIME_S)
    if far.size:
        i = int(far[0])
        raise InputError(f"{path}: line {lines[i]}, column '{TIME}': {t[i]:g} s is beyond "
                         f"{MAX_TIME_S:g} s; times are seconds since the log started")
    steps = np.diff(t)
    bad = np.flatnonzero(steps <= 0)
    if bad.size:
        i = int(bad[0]) + 1
        raise InputError(f"{path}: line {lines[i]}, column '{TIME}': time {t[i]:g} s does not "
                         f"increase (previous row: {t[i - 1]:g} s); rows must be in time order")


def require(table: SampleTable, names: tuple[str, ...], what: str) -> None:
    missing = [n for n in names if n not in table.columns]
    if missing:
        raise InputError(f"{table.path}: missing column(s) {', '.join(missing)} needed for "
                         f"{what}; header must include {', '.join(names)}")
