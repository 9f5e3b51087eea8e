"""Reading the log ``imuhal run --output LOG.csv --samples`` writes (docs/output-csv.md).

That log is long: one row per event, ``kind`` saying which columns it fills. Its sample rows
become the same sample objects the pipeline produced (body frame NED, project units) in the
same order, so an estimator run over it offline sees what it would have seen live. Flagged
samples (``flags`` not 0) are skipped, as the pipeline never fuses them; estimate rows are
the run's own outputs and are not inputs.
"""

from __future__ import annotations

import csv
import math
from dataclasses import dataclass
from pathlib import Path

from imuhal.core.conventions import CONVENTIONS, NED, Convention, VectorKind, vector_to_ned
from imuhal.core.samples import (
    AccelSample,
    Frame,
    GyroSample,
    MagSample,
    PressureSample,
    Sample,
    TemperatureSample,
    VectorSample,
)
from imuhal.estimation.framed import frame_suffix
from imuhal.offline.csv_input import InputError

LONG_FORMAT_COLUMNS = frozenset({"t_s", "source", "kind", "flags"})
"""A header with all of these is a run log (long format), not a wide sample table."""

_VECTORS: dict[str, tuple[tuple[str, str, str], type[VectorSample], str, VectorKind]] = {
    "accel": (("ax_m_s2", "ay_m_s2", "az_m_s2"), AccelSample, "accel_m_s2",
              VectorKind.SPECIFIC_FORCE),
    "gyro": (("gx_rad_s", "gy_rad_s", "gz_rad_s"), GyroSample, "gyro_rad_s",
             VectorKind.ANGULAR_RATE),
    "mag": (("mx_ut", "my_ut", "mz_ut"), MagSample, "mag_ut", VectorKind.MAGNETIC_FIELD),
}
_DECODED_KINDS = frozenset({*_VECTORS, "pressure", "temperature"})


@dataclass
class RunLog:
    path: Path
    samples: list[Sample]
    """Valid samples in log order."""
    rows: int
    """Data rows in the file."""
    flagged: int
    """Sample rows skipped because they were flagged."""
    skipped: dict[str, int]
    """Rows of other kinds by kind: estimates (outputs, not inputs) and samples the log has
    no columns for (velocity, airspeed)."""


def is_run_log(path: str | Path) -> bool:
    """True when the file's header is a run log's (``t_s, source, kind, flags, ...``)."""
    try:
        with Path(path).open(newline="", encoding="utf-8") as f:
            header = next(csv.reader(f), [])
    except (OSError, UnicodeDecodeError):
        return False  # the wide reader reports unreadable files with their reason
    return {h.strip() for h in header} >= LONG_FORMAT_COLUMNS


def log_frame(path: Path, header: list[str], requested: Convention | None) -> Convention:
    """The frame of a run log's body vectors: the suffix its columns carry (``ax_m_s2_enu``,
    written with ``output_frame``), else ``requested``, else ned."""
    suffixed = {c.name: c for c in CONVENTIONS.values() if c is not NED
                and f"ax_m_s2{frame_suffix(c)}" in header}
    if len(suffixed) > 1:
        raise InputError(f"{path}: vector columns in more than one frame "
                         f"({', '.join(sorted(suffixed))}); keep one frame per file")
    if not suffixed:
        return requested or NED
    (frame,) = suffixed.values()
    if requested is not None and requested is not frame:
        raise InputError(f"{path}: the log's columns are in frame '{frame.name}' but "
                         f"--input-frame {requested.name} was given; drop --input-frame")
    return frame


def read_run_log(path: str | Path, frame: Convention | None = None) -> RunLog:
    """Every valid sample of a run log, in NED body axes (from the frame its column names
    carry, else ``frame``, else ned); each bad cell is an error naming line and column."""
    p = Path(path)
    samples: list[Sample] = []
    rows = flagged = 0
    skipped: dict[str, int] = {}
    with p.open(newline="", encoding="utf-8") as f:
        reader = csv.DictReader(f)
        header = [h.strip() for h in reader.fieldnames or []]
        conv = log_frame(p, header, frame)
        # Columns without a frame suffix are read in the frame --input-frame names.
        suffix = frame_suffix(conv) if f"ax_m_s2{frame_suffix(conv)}" in header else ""
        for line_no, row in enumerate(reader, start=2):
            rows += 1
            kind = (row.get("kind") or "").strip()
            if not kind:
                raise InputError(f"{p}: line {line_no}, column 'kind': empty; every row of a "
                                 "run log names its kind (docs/output-csv.md)")
            if kind not in _DECODED_KINDS:
                # Estimates are outputs; other samples (velocity, airspeed) have no columns
                # in the log to rebuild them from.
                skipped[kind] = skipped.get(kind, 0) + 1
                continue
            if _number(p, line_no, row, "flags") != 0:
                flagged += 1
                continue
            t_ns = round(_number(p, line_no, row, "t_s") * 1e9)
            device = (row.get("source") or "").strip()
            if kind in _VECTORS:
                names, cls, field, vector_kind = _VECTORS[kind]
                vector = tuple(_number(p, line_no, row, n + suffix) for n in names)
                if conv is not NED:
                    vector = tuple(float(x) for x in vector_to_ned(vector, conv, vector_kind))
                samples.append(cls(t_ns=t_ns, device=device, frame=Frame.BODY_NED,
                                   **{field: vector}))  # type: ignore[arg-type]  # field is the vector field of cls (_VECTORS pairs them)
            elif kind == "pressure":
                samples.append(PressureSample(t_ns=t_ns, device=device, pressure_pa=_number(
                    p, line_no, row, "pressure_pa")))
            else:  # temperature
                samples.append(TemperatureSample(t_ns=t_ns, device=device,
                                                 temperature_degc=_number(
                                                     p, line_no, row, "temperature_degc")))
    if not samples:
        others = ", ".join(f"{n} {k}" for k, n in sorted(skipped.items())) or "none"
        why = (f"it holds no valid samples to rebuild (accel, gyro, mag, pressure, "
               f"temperature; other rows: {others}); write samples with `imuhal run --output "
               "LOG.csv --samples`") if rows else "it has no data rows"
        raise InputError(f"{p}: no samples to estimate from: {why}")
    return RunLog(p, samples, rows, flagged, skipped)


def _number(path: Path, line_no: int, row: dict[str, str | None], column: str) -> float:
    text = (row.get(column) or "").strip()
    try:
        value = float(text)
    except ValueError:
        raise InputError(f"{path}: line {line_no}, column '{column}': {text!r} is not a "
                         "number") from None
    if not math.isfinite(value):
        raise InputError(f"{path}: line {line_no}, column '{column}': {text!r} is not finite "
                         "in a valid (flags 0) sample row")
    return value
