"""Ground-truth recording: a documented CSV of a scenario's true state, written atomically.

Format (docs/simulation.md has the full table): optional ``#`` comment lines first
(``# imuhal-truth v1``, then ``# key=value`` metadata such as scenario, seed, params JSON),
then one header row and one row per timestamp. Floats are written with ``repr`` so they
read back bit for bit; a missing disturbance is written as empty cells.
"""

from __future__ import annotations

import csv
import io
import json
import os
from collections.abc import Iterable, Mapping
from pathlib import Path

import numpy as np

from imuhal.core.atomic import atomic_write_text
from imuhal.sim.scenario import Scenario, TruthState

FORMAT_LINE = "imuhal-truth v1"

COLUMNS: tuple[str, ...] = (
    "t_s",
    "qw", "qx", "qy", "qz",
    "roll_deg", "pitch_deg", "yaw_deg",
    "wx_rad_s", "wy_rad_s", "wz_rad_s",
    "fx_m_s2", "fy_m_s2", "fz_m_s2",
    "pn_m", "pe_m", "pd_m",
    "vn_m_s", "ve_m_s", "vd_m_s",
    "altitude_m", "climb_m_s",
    "pressure_pa", "temperature_degc",
    "mx_ut", "my_ut", "mz_ut",
    "dist_n_ut", "dist_e_ut", "dist_d_ut",
)
"""Column names; units are in the names (body axes for w, f and m; NED for p, v, dist)."""


def truth_row(s: TruthState) -> list[float | str]:
    roll, pitch, yaw = s.euler_deg
    dist: list[float | str] = ["", "", ""] if s.magnetic_disturbance_ned_ut is None else \
        [float(x) for x in s.magnetic_disturbance_ned_ut]
    return [s.t_s, *map(float, s.q_body_to_ned), roll, pitch, yaw,
            *map(float, s.angular_rate_body_rad_s), *map(float, s.specific_force_body_m_s2),
            *map(float, s.position_ned_m), *map(float, s.velocity_ned_m_s),
            s.altitude_m, s.climb_m_s, float(s.pressure_pa), float(s.temperature_degc),
            *map(float, s.magnetic_field_body_ut), *dist]


def _fmt(x: float | str) -> str:
    return x if isinstance(x, str) else repr(float(x))


def write_truth_csv(path: str | os.PathLike[str], states: Iterable[TruthState], *,
                    metadata: Mapping[str, object] | None = None) -> Path:
    """Write truth states (in the given order) to ``path`` atomically."""
    buf = io.StringIO()
    buf.write(f"# {FORMAT_LINE}\n")
    for key, value in (metadata or {}).items():
        text = value if isinstance(value, str) else json.dumps(value, sort_keys=True)
        if "\n" in key or "\n" in text or "=" in key:
            raise ValueError(f"metadata {key!r} must be one line and its key free of '='")
        buf.write(f"# {key}={text}\n")
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(COLUMNS)
    for s in states:
        w.writerow([_fmt(x) for x in truth_row(s)])
    Path(path).parent.mkdir(parents=True, exist_ok=True)
    return atomic_write_text(path, buf.getvalue())


def record_truth(path: str | os.PathLike[str], scenario: Scenario,
                 times_s: Iterable[float]) -> Path:
    """Evaluate ``scenario`` at ``times_s`` and write the truth CSV, with the scenario's
    name, seed and parameters as metadata."""
    meta = {"scenario": scenario.name, "seed": scenario.seed,
            "params": scenario.params.model_dump(mode="json")}
    return write_truth_csv(path, (scenario.truth(float(t)) for t in times_s), metadata=meta)


def read_truth_csv(path: str | os.PathLike[str]) -> tuple[dict[str, np.ndarray], dict[str, str]]:
    """(columns by name as float arrays, metadata). Empty cells read as NaN."""
    meta: dict[str, str] = {}
    lines: list[str] = []
    with open(path, encoding="utf-8", newline="") as f:
        for line in f:
            if line.startswith("#"):
                body = line[1:].strip()
                if "=" in body:
                    k, v = body.split("=", 1)
                    meta[k.strip()] = v
                elif body:
                    meta.setdefault("format", body)
            else:
                lines.append(line)
    try:
        rows = list(csv.reader(lines))
    except csv.Error as exc:  # a cell over the csv module's field limit, a NUL byte
        raise ValueError(f"not CSV text: {exc}") from None
    if not rows:
        raise ValueError(f"{path}: no header row")
    header, body_rows = rows[0], rows[1:]
    data = np.array([[float(x) if x != "" else np.nan for x in r] for r in body_rows],
                    dtype=float).reshape(len(body_rows), len(header))
    return {name: data[:, i] for i, name in enumerate(header)}, meta


def truth_states_from_columns(cols: Mapping[str, np.ndarray]) -> list[TruthState]:
    """Rebuild TruthStates from :func:`read_truth_csv` columns."""
    def vec(*names: str) -> np.ndarray:
        return np.column_stack([cols[n] for n in names])

    q = vec("qw", "qx", "qy", "qz")
    w = vec("wx_rad_s", "wy_rad_s", "wz_rad_s")
    f = vec("fx_m_s2", "fy_m_s2", "fz_m_s2")
    p = vec("pn_m", "pe_m", "pd_m")
    v = vec("vn_m_s", "ve_m_s", "vd_m_s")
    m = vec("mx_ut", "my_ut", "mz_ut")
    d = vec("dist_n_ut", "dist_e_ut", "dist_d_ut") if "dist_n_ut" in cols else None
    out = []
    for i, t in enumerate(cols["t_s"]):
        dist = None if d is None or np.isnan(d[i]).any() else d[i].copy()
        out.append(TruthState(float(t), q[i].copy(), w[i].copy(), f[i].copy(), p[i].copy(),
                              v[i].copy(), m[i].copy(), float(cols["pressure_pa"][i]),
                              float(cols["temperature_degc"][i]), dist))
    return out
