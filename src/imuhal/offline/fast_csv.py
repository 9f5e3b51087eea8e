"""Numbers from and to CSV text a whole block at a time, through orjson (the ``fast`` extra).

``imuhal estimate`` spends most of its time on text, not on filters: Python's ``float()`` per
cell on the way in and ``repr()`` per cell on the way out cost several microseconds a row,
where the compiled filter step costs a tenth of one. orjson parses and prints numbers in
compiled code with the same results, so a block of CSV lines becomes one JSON array and a
block of numeric columns one JSON text:

- **Reading** (:func:`parse_block`): a JSON number is a subset of what ``float()`` reads, and
  orjson rounds it correctly, as ``float()`` does; empty cells become ``null`` (NaN). Text
  that is not plainly numbers and commas (quotes, spaces, ``nan``, ``+1``, ``.5``, a row of
  another width, a blank line, ``-0``, which JSON reads as the integer 0 and so loses its
  sign) is handed back (None) to the strict reader, which reads it as before and names any
  bad cell. The results are therefore bit for bit those of ``float()`` per cell.
- **Writing** (:func:`format_block`): orjson prints the shortest text that reads back to the
  same double, as ``repr`` does, and with the same digits; its notation differs from
  ``repr``'s only below 1e-4 (``0.00001`` for ``1e-05``). Rows holding such a value, or a
  value that is not finite (which imuhal writes ``nan``), are written by ``repr`` row by
  row, so the text is byte for byte ``repr``'s.

``IMUHAL_FAST_CSV=0`` (or orjson not installed) turns both off: the csv module and
``float``/``repr`` per cell, same results, slower.
"""

from __future__ import annotations

import math
import os
from collections.abc import Sequence
from types import ModuleType
from typing import Any

import numpy as np

ENV = "IMUHAL_FAST_CSV"

_ALLOWED = b"0123456789.,eE+-\r\n"
"""Bytes a block of plain numbers may hold; anything else goes to the strict reader."""

_SMALL = 1e-4
"""Below this magnitude ``repr`` switches to exponent notation and orjson does not."""


def engine() -> Any | None:
    """orjson, unless it is not installed or ``IMUHAL_FAST_CSV=0`` turns it off."""
    if os.environ.get(ENV, "1") == "0":
        return None
    return _orjson()


def _orjson() -> ModuleType | None:
    try:
        import orjson
    except ImportError:
        return None
    return orjson


def parse_block(data: bytes, rows: int, width: int, sparse: Sequence[bool]
                ) -> np.ndarray | None:
    """The (``rows``, ``width``) float64 values of ``data`` (``rows`` whole CSV lines, each
    ending in a newline), NaN for an empty cell of a ``sparse`` column; None when the text
    needs the strict reader (see the module docstring) or orjson is off."""
    orjson = engine()
    if orjson is None or not rows or data.translate(None, _ALLOWED):
        return None
    if b"\r" in data:
        data = data.replace(b"\r\n", b"\n")
    # each line ends in a string sentinel: a row of another width moves them, which is seen
    text = data.replace(b"\n", b',"",')
    empty = b",," in text or text.startswith(b",")
    if empty:
        text = (b"null" + text if text.startswith(b",") else text)
        text = text.replace(b",,", b",null,").replace(b",,", b",null,")
    try:
        cells = orjson.loads(b"".join((b"[", memoryview(text)[:-1], b"]")))
    except orjson.JSONDecodeError:
        return None
    step = width + 1
    ends = cells[width::step]
    if len(cells) != rows * step or len(ends) != rows or ends.count("") != rows:
        return None
    del cells[width::step]
    # numbers only (the byte check) and, without empty cells, no None: fromiter is quicker
    values = (np.array(cells, dtype=np.float64) if empty else
              np.fromiter(cells, dtype=np.float64, count=len(cells))).reshape(rows, width)
    if not _plain(values, sparse):
        return None
    if not values.all() and _negative_zero_text(data):
        return None  # "-0" read as the integer 0: the strict reader keeps the sign
    return values


def _plain(values: np.ndarray, sparse: Sequence[bool]) -> bool:
    """Every value finite, except the NaN of an empty cell in a sparse column."""
    finite = np.isfinite(values)
    if finite.all():
        return True
    empty_allowed = np.asarray(sparse, dtype=bool)
    return bool((finite | (np.isnan(values) & empty_allowed)).all())


def _negative_zero_text(data: bytes) -> bool:
    return (b"-0," in data or b"-0\n" in data) or data.endswith(b"-0")


def format_block(columns: Sequence[np.ndarray]) -> bytes | None:
    """The CSV lines (``\\r\\n`` after each) of equally long numeric columns (float64, or
    integers), each cell as ``repr`` writes it (a non-finite float as ``nan``); None when
    orjson is off or a column is neither."""
    orjson = engine()
    if orjson is None or not columns:
        return None
    if any(c.dtype.kind not in "fiub" for c in columns):
        return None
    cols = [c.astype(np.int64) if c.dtype.kind in "ub" else c for c in columns]
    n = len(cols[0])
    odd = np.zeros(n, dtype=bool)
    for c in cols:
        if c.dtype.kind == "f":
            a = np.abs(c)
            odd |= ~np.isfinite(c) | ((a < _SMALL) & (a > 0))
    runs = _runs(cols)
    pieces: list[bytes] = []
    start = 0
    for i in np.flatnonzero(odd).tolist():  # rows repr must write: rare in real logs
        if i > start:
            pieces.append(_orjson_rows(orjson, runs, start, i))
        pieces.append(_repr_row(cols, i))
        start = i + 1
    if start < n:
        pieces.append(_orjson_rows(orjson, runs, start, n))
    return b"".join(pieces)


def _runs(cols: list[np.ndarray]) -> list[np.ndarray]:
    """Neighbouring columns of one kind (float64 or int64) as one array each: (n,) for a
    column alone, else (n, k)."""
    runs: list[list[np.ndarray]] = []
    for c in cols:
        if runs and runs[-1][0].dtype == c.dtype:
            runs[-1].append(c)
        else:
            runs.append([c])
    return [np.ascontiguousarray(r[0]) if len(r) == 1 else np.column_stack(r) for r in runs]


def _orjson_rows(orjson: Any, runs: list[np.ndarray], start: int, stop: int) -> bytes:
    """Rows ``start:stop`` of the runs' columns as CSV lines, each run printed by orjson
    (a float as a float, an integer as an integer) and the runs' texts joined row by row."""
    option = orjson.OPT_SERIALIZE_NUMPY
    if len(runs) == 1 and runs[0].ndim == 2:  # one array: no Python object per row
        return orjson.dumps(runs[0][start:stop], option=option)[2:-2].replace(
            b"],[", b"\r\n") + b"\r\n"
    parts = [orjson.dumps(r[start:stop], option=option)[2:-2].split(b"],[") if r.ndim == 2
             else orjson.dumps(r[start:stop], option=option)[1:-1].split(b",") for r in runs]
    return b"\r\n".join(map(b",".join, zip(*parts, strict=True))) + b"\r\n"


def _repr_row(cols: list[np.ndarray], i: int) -> bytes:
    return ",".join(repr(v) if not isinstance(v, float) or math.isfinite(v) else "nan"
                    for v in (c[i].item() for c in cols)).encode("ascii") + b"\r\n"


def format_column(values: np.ndarray) -> list[str] | None:
    """Each value of a float64 or integer column as ``repr`` writes it (a non-finite float
    as ``nan``); None when orjson is off or the column is neither."""
    text = format_block([values])
    return None if text is None else text.decode("ascii").split("\r\n")[:-1]
