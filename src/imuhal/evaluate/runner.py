"""Running estimators over recordings: one job per trial x estimator x setting x DOF.

A job builds the estimator from its registry name and settings, feeds the recording's rows
through the same offline path as ``imuhal estimate`` (imuhal.offline.runner: the samples and
estimates the pipeline would produce), matches each estimate to its row by time stamp and
takes BROAD's errors over the recording's mask. Rows the estimator gave no attitude for stay
NaN and are counted as ``missing``. Estimators with ``offline: true`` (the whole recording
known in advance) run through their ``smooth`` method, as in ``imuhal estimate``.

The rate settings the user did not give are set from the recording's rate, as a profile
would set them for its board (``RATE_SETTINGS``): an estimator that integrates over a nominal
period would otherwise integrate the gyro with the wrong step.
"""

from __future__ import annotations

import itertools
import time
from collections.abc import Callable, Iterable, Iterator, Sequence
from dataclasses import asdict, dataclass, field
from typing import Any

import numpy as np

from imuhal.core.frames import FloatArray
from imuhal.estimation.outputs import AttitudeEstimate
from imuhal.estimation.rows import AttitudeRows
from imuhal.evaluate.metrics import rmse_deg
from imuhal.evaluate.recording import Recording, RecordingSource
from imuhal.offline.csv_input import ACCEL, GYRO, MAG, TIME, SampleTable
from imuhal.offline.runner import run_offline_columns
from imuhal.offline.settings_args import build_settings
from imuhal.plugins.manager import Registry

RATE_SETTINGS: dict[str, Callable[[float], float]] = {
    "sample_period_s": lambda rate_hz: 1.0 / rate_hz,  # every AHRS (common/ahrs.py), vqf
    "sensor_rate_hz": lambda rate_hz: rate_hz,  # the Freescale filters' SENSORFS
}
"""Setting name -> its value from the recording's sample rate (Hz)."""


@dataclass(frozen=True)
class EstimatorSpec:
    """One estimator configuration: registry name, its settings, and a label for tables."""

    name: str
    settings: dict[str, Any] = field(default_factory=dict)
    dof: int = 9
    """9: gyro, accelerometer and magnetometer; 6: the magnetometer is withheld."""

    @property
    def label(self) -> str:
        parts = [self.name, *(f"{k}={_fmt_value(v)}" for k, v in self.settings.items())]
        return " ".join(parts)


def _fmt_value(v: Any) -> str:
    if isinstance(v, list | tuple):
        return ",".join(_fmt_value(x) for x in v)
    if v is None:
        return "null"
    return str(v).lower() if isinstance(v, bool) else str(v)


def expand_grid(specs: Sequence[EstimatorSpec],
                grid: dict[str, dict[str, list[Any]]]) -> list[EstimatorSpec]:
    """Every spec once per combination of its estimator's grid values (``grid``: estimator
    name -> setting -> values); a value given in the spec itself wins over the grid."""
    out: list[EstimatorSpec] = []
    for spec in specs:
        axes = {k: v for k, v in grid.get(spec.name, {}).items() if k not in spec.settings}
        if not axes:
            out.append(spec)
            continue
        for combo in itertools.product(*axes.values()):
            out.append(EstimatorSpec(spec.name, {**spec.settings,
                                                 **dict(zip(axes, combo, strict=True))},
                                     spec.dof))
    return out


@dataclass(frozen=True)
class TrialResult:
    """One job's errors (degrees) and what it cost."""

    trial: str
    groups: tuple[str, ...]
    estimator: str
    label: str
    dof: int
    total_deg: float
    heading_deg: float
    inclination_deg: float
    evaluated: int
    missing: int
    seconds: float

    def as_row(self) -> dict[str, Any]:
        row = asdict(self)
        row["groups"] = " ".join(self.groups)
        return row


def recording_table(rec: Recording, dof: int) -> SampleTable:
    """The recording's rows as the sample table ``imuhal estimate`` would read."""
    columns: dict[str, np.ndarray] = {TIME: rec.t_s}
    for names, values in ((GYRO, rec.gyro_rad_s), (ACCEL, rec.accel_m_s2)):
        columns.update({n: values[:, i] for i, n in enumerate(names)})
    if dof == 9 and rec.mag_ut is not None:
        columns.update({n: rec.mag_ut[:, i] for i, n in enumerate(MAG)})
    from pathlib import Path

    return SampleTable(Path(rec.name), columns, np.arange(2, len(rec) + 2))


def with_rate_settings(fields: Iterable[str], values: dict[str, Any],
                       rate_hz: float) -> dict[str, Any]:
    """``values`` plus every ``RATE_SETTINGS`` entry the estimator has and the user left out."""
    out = dict(values)
    for key, from_rate in RATE_SETTINGS.items():
        if key in fields and key not in out:
            out[key] = from_rate(rate_hz)
    return out


def estimate_quaternions(rec: Recording, spec: EstimatorSpec, registry: Registry) -> FloatArray:
    """(N, 4) body -> NED estimates on the recording's rows (NaN where none)."""
    cls = registry.estimators.get(spec.name)
    values = with_rate_settings(cls.Settings.model_fields, spec.settings, rec.rate_hz)
    settings = build_settings(cls.Settings, values, spec.name)
    estimator = cls(settings)
    # whole rows at once where the estimator takes them (compiled with numba): same values
    outputs = run_offline_columns(estimator, recording_table(rec, spec.dof))
    t_ns = np.round(rec.t_s * 1e9).astype(np.int64)
    q = np.full((len(rec), 4), np.nan)
    if isinstance(outputs, AttitudeRows):
        est_t, est_q = outputs.t_ns, outputs.q_body_to_ned
    else:
        atts = [e for e in outputs if isinstance(e, AttitudeEstimate)]
        est_t = np.array([e.t_ns for e in atts], dtype=np.int64)
        est_q = np.array([e.q_body_to_ned for e in atts]).reshape(-1, 4)
    if len(est_t):
        rows = np.searchsorted(t_ns, est_t)
        ok = (rows < len(t_ns)) & (t_ns[np.minimum(rows, len(t_ns) - 1)] == est_t)
        q[rows[ok]] = est_q[ok]
    return q


def run_job(rec: Recording, spec: EstimatorSpec, registry: Registry) -> TrialResult:
    """One trial with one estimator setting."""
    start = time.perf_counter()
    q = estimate_quaternions(rec, spec, registry)
    err = rmse_deg(q, rec.q_truth, rec.mask)
    return TrialResult(trial=rec.name, groups=rec.groups, estimator=spec.name, label=spec.label,
                       dof=spec.dof, total_deg=err.total_deg, heading_deg=err.heading_deg,
                       inclination_deg=err.inclination_deg, evaluated=err.evaluated,
                       missing=err.missing, seconds=time.perf_counter() - start)


Progress = Callable[[int, int, TrialResult], None]


def evaluate_serial(sources: Iterable[RecordingSource], specs: Sequence[EstimatorSpec],
                    registry: Registry, progress: Progress | None = None) -> list[TrialResult]:
    """Every source with every spec, in order (each recording loaded once)."""
    sources = list(sources)
    total = len(sources) * len(specs)
    results: list[TrialResult] = []
    for src in sources:
        rec = src.load()
        for spec in specs:
            results.append(run_job(rec, spec, registry))
            if progress is not None:
                progress(len(results), total, results[-1])
    return results


def jobs(sources: Sequence[RecordingSource],
         specs: Sequence[EstimatorSpec]) -> Iterator[tuple[RecordingSource, EstimatorSpec]]:
    """The job list in the serial run's order."""
    for src in sources:
        for spec in specs:
            yield src, spec
