"""Whole chunks of IMU rows in and attitude rows out: the column form of ``process()``.

``imuhal estimate`` and ``evaluate`` feed a wide log (one row per time) to an attitude
estimator. Row by row that is three sample objects in and one estimate object out per row,
which costs more than the filter itself. An estimator that can also take the chunk at once
implements :class:`RowsEstimator`: it gets :class:`ImuRows` (the samples ``process()`` would
have got, as arrays) and returns :class:`AttitudeRows` (the estimates it would have made, as
arrays). The results are those of ``process()`` (which stays the reference); only the
representation differs.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Protocol, runtime_checkable

import numpy as np

from imuhal.core.frames import FloatArray

DiagnosticColumn = np.ndarray | list[Any]
"""One diagnostics column: an int array (flags, counts), a float array, or Python values
(None where a row has no value)."""


@dataclass(frozen=True)
class ImuRows:
    """One chunk of a wide IMU log, in time order; body NED axes, project units.

    Each row is what the offline runner feeds ``process()`` in fusion order: an accelerometer
    sample, a magnetometer sample when ``mag_ut[i, 0]`` is not NaN, then a gyro sample, all at
    ``t_ns[i]``."""

    t_ns: np.ndarray
    """(n,) int64 timestamps (ns)."""
    gyro_rad_s: FloatArray
    """(n, 3) rad/s."""
    accel_m_s2: FloatArray
    """(n, 3) specific force, m/s^2."""
    mag_ut: FloatArray | None
    """(n, 3) uT; a row whose first component is NaN has no magnetometer sample."""

    def __len__(self) -> int:
        return len(self.t_ns)


@dataclass(frozen=True)
class AttitudeRows:
    """The attitude estimates of one chunk, as columns (one row per estimate, in time order).

    ``diagnostics`` holds the columns ``imuhal estimate`` writes after the attitude, named
    and ordered as :func:`flatten_diagnostics` names them for the CSV writer (booleans
    as 0/1, vectors as ``name_0``...); text-valued diagnostics are left out, as the CSV
    leaves them out. The gravity-compensated acceleration is not carried."""

    source: str
    t_ns: np.ndarray
    """(m,) int64 ns."""
    q_body_to_ned: FloatArray
    """(m, 4) unit quaternions (w, x, y, z), body -> NED."""
    diagnostics: dict[str, DiagnosticColumn]

    def __len__(self) -> int:
        return len(self.t_ns)


@runtime_checkable
class RowsEstimator(Protocol):
    """An estimator that also takes a chunk of rows at once (see the module docstring)."""

    def process_imu_rows(self, rows: ImuRows) -> AttitudeRows:
        """What ``process()`` makes of ``rows`` (its state carries on to the next chunk)."""
        ...


def flatten_diagnostics(diag: dict[str, Any], prefix: str = "") -> dict[str, Any]:
    """Numbers, booleans and short vectors as columns (``gyro_bias_rad_s_0`` ...): booleans
    as 0/1; text and None are left out."""
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


def merge_columns(first: list[dict[str, Any]], then: dict[str, DiagnosticColumn],
                  n_then: int) -> dict[str, DiagnosticColumn]:
    """Columns of rows given as flattened dictionaries (``first``) followed by ``n_then``
    rows given as columns (``then``): names in order of first appearance, None where a row
    has no value for a name."""
    if not first:
        return then
    names = dict.fromkeys([*(k for d in first for k in d), *then])
    merged: dict[str, DiagnosticColumn] = {}
    for k in names:
        col = [d.get(k) for d in first]
        if n_then:
            tail = then.get(k)
            col += [None] * n_then if tail is None else list(np.asarray(tail).tolist())
        merged[k] = col
    return merged
