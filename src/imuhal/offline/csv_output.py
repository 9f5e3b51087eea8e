"""Writing estimator outputs: fixed leading columns per estimate type, then diagnostics."""

from __future__ import annotations

import csv
import math
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from imuhal.core.atomic import AtomicFile
from imuhal.core.conventions import NED, Convention
from imuhal.estimation.framed import attitude_columns, express_attitude
from imuhal.estimation.outputs import AttitudeEstimate, Estimate, VerticalEstimate

ATTITUDE_COLUMNS = ("t_s", *attitude_columns(NED))
VERTICAL_COLUMNS = ("t_s", "altitude_m", "climb_m_s", "accel_bias_m_s2")


def estimate_fields(e: Estimate, frame: str | Convention = NED) -> dict[str, Any]:
    """The leading columns of one estimate; an attitude's quaternion (body -> earth) and
    Euler angles in ``frame``, named with its suffix (none for ned)."""
    if isinstance(e, AttitudeEstimate):
        a = express_attitude(e, frame)
        return dict(zip(("t_s", *attitude_columns(frame)),
                        (e.t_ns / 1e9, *a.q_body_to_earth, *a.euler_deg), strict=True))
    if isinstance(e, VerticalEstimate):
        bias = e.accel_bias_m_s2
        return {"t_s": e.t_ns / 1e9, "altitude_m": e.altitude_m, "climb_m_s": e.climb_m_s,
                "accel_bias_m_s2": "" if bias is None else bias}
    return {"t_s": e.t_ns / 1e9}


def flatten_diagnostics(diag: dict[str, Any], prefix: str = "") -> dict[str, Any]:
    """Numbers, booleans and short vectors as columns (``gyro_bias_rad_s_0`` ...)."""
    out: dict[str, Any] = {}
    for key, value in diag.items():
        name = f"{prefix}{key}"
        if isinstance(value, bool):
            out[name] = int(value)
        elif isinstance(value, int | float):
            out[name] = value
        elif isinstance(value, list | tuple) and all(isinstance(v, int | float) for v in value):
            for i, v in enumerate(value):
                out[f"{name}_{i}"] = v
        elif isinstance(value, dict):
            out.update(flatten_diagnostics(value, f"{name}_"))
    return out


def write_estimates(path: str | Path, estimates: Sequence[Estimate],
                    frame: str | Convention = NED) -> int:
    """Write ``estimates`` atomically, attitudes in ``frame``; returns the number of rows.
    Diagnostic columns stay as each estimator reports them (its internal NED body frame)."""
    rows = []
    diag_cols: dict[str, None] = {}
    base: tuple[str, ...] = ("t_s",)
    for e in estimates:
        fields = estimate_fields(e, frame)
        if len(fields) > len(base):
            base = tuple(fields)
        diag = flatten_diagnostics(e.diagnostics)
        for k in diag:
            diag_cols.setdefault(k, None)
        rows.append((fields, diag))
    header = list(base) + [k for k in diag_cols if k not in base]
    with AtomicFile(path, newline="") as f:
        writer = csv.writer(f)
        writer.writerow(header)
        for fields, diag in rows:
            merged = {**diag, **fields}
            writer.writerow([_fmt(merged.get(h, "")) for h in header])
    return len(rows)


def _fmt(v: Any) -> str:
    if isinstance(v, float):
        return repr(v) if math.isfinite(v) else "nan"
    return str(v)
