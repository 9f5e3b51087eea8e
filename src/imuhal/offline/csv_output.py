"""Writing estimator outputs: fixed leading columns per estimate type, then diagnostics."""

from __future__ import annotations

import contextlib
import csv
import io
import math
import shutil
import tempfile
from collections.abc import Collection, Iterable, Sequence
from pathlib import Path
from typing import IO, Any

import numpy as np

from imuhal.core.atomic import AtomicFile
from imuhal.core.conventions import NED, Convention, get_convention
from imuhal.core.errors import ImuhalError, OutputError
from imuhal.estimation.framed import attitude_columns, express_attitude
from imuhal.estimation.outputs import (
    AttitudeEstimate,
    Estimate,
    RejectedEstimate,
    VerticalEstimate,
)
from imuhal.estimation.rows import AttitudeRows, flatten_diagnostics
from imuhal.offline.fast_csv import format_block, format_column

ATTITUDE_COLUMNS = ("t_s", *attitude_columns(NED))
VERTICAL_COLUMNS = ("t_s", "altitude_m", "climb_m_s", "accel_bias_m_s2")


def estimate_fields(e: Estimate, frame: str | Convention = NED) -> dict[str, Any]:
    """The leading columns of one estimate; an attitude's quaternion (body -> earth) and
    Euler angles in ``frame``, named with its suffix (none for ned)."""
    if isinstance(e, AttitudeEstimate):
        a = express_attitude(e, frame)
        return dict(zip(("t_s", *attitude_columns(frame)),
                        (e.t_ns / 1e9, *a.q_body_to_earth, *a.euler_deg), strict=True))
    if isinstance(e, RejectedEstimate):
        # refused (imuhal.estimation.outputs.estimate_flags): why, never a value
        return {"t_s": e.t_ns / 1e9, "flags": int(e.flags)}
    if isinstance(e, VerticalEstimate):
        bias = e.accel_bias_m_s2
        return {"t_s": e.t_ns / 1e9, "altitude_m": e.altitude_m, "climb_m_s": e.climb_m_s,
                "accel_bias_m_s2": "" if bias is None else bias}
    return {"t_s": e.t_ns / 1e9}


def write_estimates(path: str | Path, estimates: Sequence[Estimate],
                    frame: str | Convention = NED) -> int:
    """Write ``estimates`` atomically, attitudes in ``frame``; returns the number of rows.
    Diagnostic columns stay as each estimator reports them (its internal NED body frame)."""
    writer = EstimateCsvWriter(path, frame)
    try:
        writer.write(estimates)
        return writer.commit()
    except BaseException:
        writer.abort()
        raise


class ColumnError(ImuhalError):
    """``--columns`` names a column the estimator does not write."""


class EstimateCsvWriter:
    """Writes estimates as they come, in flat memory; the file appears only on ``commit()``.

    The header is every column seen, in order of first appearance: the leading columns of the
    estimate type, then the diagnostics. The header known at the first rows and the rows go
    to the output's temporary file as they are written; ``commit`` renames it over ``path``
    atomically. Only when a later chunk brings a new column does ``commit`` write the file
    again: the whole header, then the rows, those written before the column first appeared
    padded. (A FIFO or a device as ``path`` gets nothing before ``commit``: the rows wait in a
    spill file beside it.)
    ``columns`` fixes the header to those names, in that order (no other work is done for
    the rest: only the quaternion, say); a name the first estimate does not have is a
    :class:`ColumnError` listing the ones it has.
    """

    def __init__(self, path: str | Path, frame: str | Convention = NED,
                 columns: Sequence[str] | None = None) -> None:
        self.path = Path(path)
        self.frame = frame
        self._fixed = None if columns is None else list(columns)
        self._header: list[str] = [] if columns is None else list(columns)
        self._index: dict[str, int] = {h: i for i, h in enumerate(self._header)}
        self._growth: list[tuple[int, int]] = []
        """(first row, header width) whenever the header grew after rows were written."""
        self.rows = 0
        # bytes: the block formatter's text goes to disk without a codec pass
        self._out = AtomicFile(self.path, binary=True)
        self._spill: IO[bytes] | None = None
        if self._out.direct:
            self._spill = tempfile.TemporaryFile(  # noqa: SIM115 (closed by commit/abort)
                "w+b", dir=self._out.tmp_path.parent, prefix=f".{self.path.name}.",
                suffix=".rows")
        self._written_header: list[str] | None = None
        """The header at the head of the output's temporary file (None: not yet written)."""

    def write(self, estimates: Iterable[Estimate] | AttitudeRows) -> None:
        """Append ``estimates`` (one chunk: formatted column by column, written at once);
        :class:`AttitudeRows` are written as they are, without estimate objects."""
        try:
            self._write(estimates)
        except OSError as exc:  # the spill file beside the output: a full disk, a quota
            raise OutputError(f"{self.path}: cannot be written: {exc.strerror or exc}; free "
                              "some space or choose another path") from None

    def _write(self, estimates: Iterable[Estimate] | AttitudeRows) -> None:
        if isinstance(estimates, AttitudeRows):
            self._write_rows(estimates)
            return
        chunk = list(estimates)
        if not chunk:
            return
        leading = _leading_columns(chunk, self.frame)
        columns = _diagnostic_columns(chunk)
        # numbers only (a NED attitude's fields, uniform diagnostics) need no quoting
        plain = columns is not None and all(type(e) is AttitudeEstimate for e in chunk) \
            and get_convention(self.frame) is NED
        if columns is None:  # diagnostics that differ in form from row to row
            diags = [flatten_diagnostics(e.diagnostics) for e in chunk]
            columns = {k: [_fmt(d.get(k, "")) for d in diags]
                       for k in dict.fromkeys(k for d in diags for k in d)}
        if self._fixed is None:
            known = self._index.keys()
            if not (leading.keys() <= known and columns.keys() <= known):
                self._extend([*leading, *columns])
        elif self.rows == 0:
            self._check_columns({**columns, **leading})
        blank = [""] * len(chunk)
        cells = [leading[h] if h in leading else columns.get(h, blank) for h in self._header]
        if plain:  # as _write_rows: the lines joined directly
            text = "\r\n".join(map(",".join, zip(*cells, strict=True))) + "\r\n"
        else:
            buffer = io.StringIO(newline="")
            csv.writer(buffer).writerows(zip(*cells, strict=True))
            text = buffer.getvalue()
        self._emit(text.encode("utf-8"))
        self.rows += len(chunk)

    def _write_rows(self, rows: AttitudeRows) -> None:
        """The column form of :meth:`write`: the same header and the same cells."""
        n = len(rows)
        if not n:
            return
        if self._fixed is None or self.rows == 0:
            if get_convention(self.frame) is NED:
                names: Sequence[str] = ATTITUDE_COLUMNS
            else:
                names = tuple(estimate_fields(_attitude(rows, 0), self.frame))
            # a name whose column has no value on any row is not a column (as row by row)
            present = [k for k, v in rows.diagnostics.items()
                       if not isinstance(v, list) or any(x is not None for x in v)]
            if self._fixed is None:
                if not (set(names) <= self._index.keys() and set(present) <= self._index.keys()):
                    self._extend([*names, *present])
            else:
                self._check_columns(dict.fromkeys([*names, *present]))
        text = self._numeric_block(rows)
        if text is None:
            leading = self._leading_rows(rows)
            blank = [""] * n
            cells = [leading[h] if h in leading else _fmt_column(rows.diagnostics.get(h), blank)
                     for h in self._header]
            # every cell is a number or empty, which the csv module would never quote: the
            # lines are joined directly (its per-field quoting costs more than the formatting)
            text = ("\r\n".join(map(",".join, zip(*cells, strict=True))) + "\r\n"
                    ).encode("utf-8")
        self._emit(text)
        self.rows += n

    def _numeric_block(self, rows: AttitudeRows) -> bytes | None:
        """The chunk's lines formatted a block at a time (:mod:`imuhal.offline.fast_csv`)
        when every written column is a number on every row (an NED attitude and array
        diagnostics: ``imuhal estimate``'s common case); None otherwise."""
        if get_convention(self.frame) is not NED:
            return None
        leading = _leading_arrays(rows, self._index.keys())
        columns: list[np.ndarray] = []
        for h in self._header:
            column = leading.get(h)
            if column is None:
                diagnostic = rows.diagnostics.get(h)
                if not isinstance(diagnostic, np.ndarray):  # values per row, or none
                    return None
                column = diagnostic
            columns.append(column)
        return format_block(columns)

    def _leading_rows(self, rows: AttitudeRows) -> dict[str, list[str]]:
        if get_convention(self.frame) is NED:
            # only the columns written: --columns t_s,qw,qx,qy,qz skips the Euler angles
            return {name: _fmt_floats(col)
                    for name, col in _leading_arrays(rows, self._index.keys()).items()}
        return _leading_columns([_attitude(rows, i) for i in range(len(rows))], self.frame)

    def _emit(self, lines: bytes) -> None:
        """Rows (CSV lines) after the header; the first rows write the header known now."""
        if self._spill is not None:
            self._spill.write(lines)
            return
        if self._written_header is None:
            self._written_header = list(self._header)
            self._out.write(_header_line(self._header))
        self._out.write(lines)

    def commit(self) -> int:
        """Make the output appear at ``path`` (atomically); returns the row count."""
        if self._spill is not None:  # a FIFO or device: everything now
            self._spill.seek(0)
            self._copy_rows(self._spill, self._out)
            self._spill.close()
        elif self._written_header is None:  # no rows: the header alone
            self._out.write(_header_line(self._header))
        elif self._written_header != self._header:  # a column came late: written again
            self._rewrite()
            return self.rows
        self._out.commit()
        return self.rows

    def _copy_rows(self, rows: IO[bytes], out: AtomicFile) -> None:
        """The whole header to ``out``, then ``rows``' lines, padded where they were written
        before a column first appeared."""
        out.write(_header_line(self._header))
        if not self._growth:
            shutil.copyfileobj(rows, out)
            return
        # rows before growth mark (k, w) and after the previous mark have w cells
        final = len(self._header)
        marks = iter(self._growth)
        until, width = next(marks)
        for row, line in enumerate(rows):
            while row >= until:
                until, width = next(marks, (self.rows + 1, final))
            pad = final - width
            out.write(line[:-2] + b"," * pad + b"\r\n" if pad else line)

    def _rewrite(self) -> None:
        """The output written again under its whole header (see the class docstring); the
        first temporary file is dropped."""
        first = self._out
        assert first.file is not None
        first.file.flush()
        again = AtomicFile(self.path, binary=True)
        try:
            with first.tmp_path.open("rb") as rows:
                rows.readline()  # the header the first rows were written under
                self._copy_rows(rows, again)
            again.commit()
        except BaseException:
            again.abort()
            raise
        finally:
            first.abort()

    def abort(self) -> None:
        """Drop everything written: ``path`` keeps what it had."""
        if self._spill is not None:
            with contextlib.suppress(OSError):  # after a write error, closing may fail again
                self._spill.close()
        self._out.abort()

    def _extend(self, keys: list[str]) -> None:
        """Append the columns not yet in the header (estimate fields before diagnostics)."""
        names = [k for k in dict.fromkeys(keys) if k not in self._index]
        if self.rows and names:
            self._growth.append((self.rows, len(self._header)))
        for k in names:
            self._index[k] = len(self._header)
            self._header.append(k)

    def _check_columns(self, merged: dict[str, Any]) -> None:
        missing = [c for c in self._header if c not in merged]
        if missing:
            raise ColumnError(f"--columns: {', '.join(missing)} not written by this estimator; "
                              f"its columns are: {', '.join(merged)}")


def _header_line(names: Sequence[str]) -> bytes:
    """The header as the csv module writes a row (quoted where a name needs it)."""
    line = io.StringIO(newline="")
    csv.writer(line).writerow(names)
    return line.getvalue().encode("utf-8")


def _leading_arrays(rows: AttitudeRows, wanted: Collection[str]) -> dict[str, np.ndarray]:
    """The NED attitude columns of ``rows`` named in ``wanted``, as arrays (the Euler angles
    only when one of them is wanted: ``--columns t_s,qw,qx,qy,qz`` skips them)."""
    q = rows.q_body_to_ned
    out = {"t_s": rows.t_ns.astype(float) / 1e9} if "t_s" in wanted else {}
    for name, col in zip(ATTITUDE_COLUMNS[1:5], q.T, strict=True):
        if name in wanted:
            out[name] = col
    if any(name in wanted for name in ATTITUDE_COLUMNS[5:]):
        euler = euler_deg_from_quats(q).T
        out.update(zip(ATTITUDE_COLUMNS[5:], euler, strict=True))
    return out


def _leading_columns(chunk: list[Estimate], frame: str | Convention) -> dict[str, list[str]]:
    """The estimate fields of a chunk, formatted, column by column. NED attitudes (every row
    of a plain ``imuhal estimate``) in whole arrays; anything else row by row."""
    if get_convention(frame) is NED and all(type(e) is AttitudeEstimate for e in chunk):
        q = np.array([e.q_body_to_ned for e in chunk],  # type: ignore[attr-defined]  # every e is an AttitudeEstimate (the test above)
                     dtype=np.float64)
        t_s = np.array([e.t_ns for e in chunk], dtype=float) / 1e9
        values = [t_s, *q.T, *euler_deg_from_quats(q).T]
        return {name: _fmt_floats(v) for name, v in zip(ATTITUDE_COLUMNS, values, strict=True)}
    rows = [estimate_fields(e, frame) for e in chunk]
    names = dict.fromkeys(k for r in rows for k in r)
    return {n: [_fmt(r.get(n, "")) for r in rows] for n in names}


def _diagnostic_columns(chunk: list[Estimate]) -> dict[str, list[str]] | None:
    """The diagnostics of a chunk, flattened (:func:`flatten_diagnostics`) and formatted,
    column by column, when every estimate's have the same names and each name one form
    (an AHRS's, a vario's: the common case, without a dictionary per row); else None."""
    names = tuple(chunk[0].diagnostics)
    diags = [e.diagnostics for e in chunk]
    if any(tuple(d) != names for d in diags):
        return None
    out: dict[str, list[str]] = {}
    for name in names:
        values = [d[name] for d in diags]
        kind = type(values[0])
        if any(type(v) is not kind for v in values):
            return None
        columns = _formatted(name, kind, values)
        if columns is None:
            return None
        out.update(columns)
    return out


def _formatted(name: str, kind: type, values: list[Any]) -> dict[str, list[str]] | None:
    """One diagnostic's values (all of type ``kind``) as flattened, formatted columns; {}
    for text and None (left out, as row by row); None for a form only rows can take."""
    if kind is bool or kind is int:
        return {name: _reprs([int(v) for v in values])}
    if kind is float:
        return {name: _fmt_floats(np.array(values, dtype=np.float64))}
    if kind is tuple or kind is list:
        width = len(values[0])
        if any(len(v) != width or not all(type(x) is float for x in v) for v in values):
            return None
        arr = np.array(values, dtype=np.float64).reshape(len(values), width)
        return {f"{name}_{i}": _fmt_floats(arr[:, i]) for i in range(width)}
    return {} if kind is str or kind is type(None) else None  # nested: row by row


def euler_deg_from_quats(q: np.ndarray) -> np.ndarray:
    """(n, 3) roll, pitch, yaw in degrees from (n, 4) body -> NED quaternions: the array
    form of :func:`imuhal.core.frames.euler_deg_from_quat` (same formula, same conventions)."""
    n = np.sqrt(np.einsum("ij,ij->i", q, q))
    if not np.all((n > 0) & np.isfinite(n)):
        raise ValueError("cannot normalise a zero or non-finite quaternion")
    w, x, y, z = (q / n[:, None]).T
    roll = np.arctan2(2 * (w * x + y * z), 1 - 2 * (x * x + y * y))
    pitch = np.arcsin(np.clip(2 * (w * y - z * x), -1.0, 1.0))
    yaw = np.arctan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))
    return np.degrees(np.column_stack([roll, pitch, yaw]))


def _attitude(rows: AttitudeRows, i: int) -> AttitudeEstimate:
    w, x, y, z = rows.q_body_to_ned[i].tolist()
    return AttitudeEstimate(t_ns=int(rows.t_ns[i]), source=rows.source, q_body_to_ned=(w, x, y, z))


def _fmt_column(values: np.ndarray | list | None, blank: list[str]) -> list[str]:
    """One diagnostics column of :class:`AttitudeRows` as the row-by-row writer formats it."""
    if values is None:
        return blank
    if isinstance(values, np.ndarray):
        if values.dtype.kind in "iub":
            return _reprs(values.astype(np.int64).tolist())
        return _fmt_floats(values)
    return ["" if v is None else _fmt(v) for v in values]


def _fmt_floats(values: np.ndarray) -> list[str]:
    fast = format_column(values)
    if fast is not None:
        return fast
    if np.all(np.isfinite(values)):
        return _reprs(values.tolist())
    return [_fmt(v) for v in values.tolist()]


def _reprs(values: list[float] | list[int]) -> list[str]:
    """``[repr(v) for v in values]`` for finite floats or ints, in one C-level pass (the
    list's repr joins its items' reprs with ", ")."""
    if not values:
        return []
    return repr(values)[1:-1].split(", ")


def _fmt(v: Any) -> str:
    if isinstance(v, float):
        return repr(v) if math.isfinite(v) else "nan"
    return str(v)
