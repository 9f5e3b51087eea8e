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
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from imuhal.core.errors import ImuhalError

TIME = "t_s"
GYRO = ("gx_rad_s", "gy_rad_s", "gz_rad_s")
ACCEL = ("ax_m_s2", "ay_m_s2", "az_m_s2")
MAG = ("mx_ut", "my_ut", "mz_ut")
PRESSURE = "pressure_pa"
ALTITUDE = "altitude_m"
ACCEL_UP = "accel_up_m_s2"

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


def read_sample_csv(path: str | Path, *, rate_hz: float | None = None) -> SampleTable:
    """Read and check a sample CSV. Without a ``t_s`` column, ``rate_hz`` gives the times."""
    p = Path(path)
    try:
        handle = p.open(newline="", encoding="utf-8")
    except OSError as exc:
        raise InputError(f"{p}: cannot read: {exc.strerror or exc}") from None
    with handle:
        reader = csv.reader(handle)
        try:
            header = [h.strip() for h in next(reader)]
        except StopIteration:
            raise InputError(f"{p}: the file is empty; expected a header line") from None
        dupes = {h for h in header if header.count(h) > 1}
        if dupes:
            raise InputError(f"{p}: line 1: duplicate column(s) {', '.join(sorted(dupes))}")
        rows: list[list[float]] = []
        lines: list[int] = []
        for line_no, cells in enumerate(reader, start=2):
            if not cells or all(not c.strip() for c in cells):
                continue
            if len(cells) != len(header):
                raise InputError(f"{p}: line {line_no}: {len(cells)} cells, but the header has "
                                 f"{len(header)} columns")
            rows.append([_cell(p, line_no, name, cell) for name, cell in zip(header, cells,
                                                                              strict=True)])
            lines.append(line_no)
    if not rows:
        raise InputError(f"{p}: no data rows after the header")
    data = np.array(rows, dtype=float)
    columns = {name: data[:, i] for i, name in enumerate(header)}
    line_arr = np.array(lines)
    if TIME not in columns:
        if rate_hz is None:
            raise InputError(f"{p}: missing column '{TIME}' (seconds); add it or give --rate HZ")
        columns[TIME] = np.arange(len(rows)) / rate_hz
    _check_time(p, columns[TIME], line_arr)
    return SampleTable(p, columns, line_arr)


def _cell(path: Path, line_no: int, column: str, cell: str) -> float:
    text = cell.strip()
    if not text:
        # a frame suffix (mx_ut_enu, see offline/frames.py) keeps the column sparse
        if column in SPARSE_COLUMNS or column.rsplit("_", 1)[0] in SPARSE_COLUMNS:
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
