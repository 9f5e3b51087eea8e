"""Attitude estimates as columns: what ``imuhal estimate`` and ``evaluate`` take from an
AHRS over a log's blocks.

Offline, a wide log becomes one block per quantity and chunk (imuhal.offline.runner
``imu_blocks``), which an AHRS takes at once through the same bookkeeping and compiled row
kernel as a live run's FIFO blocks (``update_blocks``). Its estimates as objects, one per
row, cost more than the filter itself (an estimate and its diagnostics dictionary per row,
then flattened again for the CSV): an estimator that can also hand them over as columns
implements :class:`RowsEstimator` and returns :class:`AttitudeRows`, the estimates
``update_blocks`` would have made, as arrays.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any, Protocol, runtime_checkable

import numpy as np

from imuhal.core.blocks import Block
from imuhal.core.frames import FloatArray

DiagnosticColumn = np.ndarray | list[Any]
"""One diagnostics column: an int array (flags, counts), a float array, or Python values
(None where a row has no value)."""


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
    """An estimator that also hands a fusion step's estimates over as columns (see the
    module docstring)."""

    def attitude_rows(self, blocks: Sequence[Block]) -> AttitudeRows:
        """The estimates ``update_blocks(blocks)`` makes, as columns (the state carries on
        to the next step as it would)."""
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
