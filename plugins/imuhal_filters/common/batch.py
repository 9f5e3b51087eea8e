"""Run an AHRS over whole arrays: the form the conformance tests and offline analyses use."""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from imuhal.core.frames import FloatArray
from imuhal_filters.common.ahrs import AhrsEstimator
from imuhal_filters.common.rows import update_rows


def run_batch(
    estimator: AhrsEstimator,
    gyro_rad_s: ArrayLike,
    accel_m_s2: ArrayLike | None = None,
    mag_ut: ArrayLike | None = None,
    dt_s: ArrayLike | float | None = None,
) -> FloatArray:
    """Step ``estimator`` once per row; return the (N, 4) body -> NED quaternions after each row.

    Arrays are N x 3 in body NED axes: gyro rad/s, accel specific force m/s^2, mag uT. ``dt_s``
    is a scalar or N values (default: the estimator's ``sample_period_s``). A row of NaN in
    ``accel_m_s2`` or ``mag_ut`` means "no sample this step". Rows for which the filter had no
    attitude yet are NaN. The estimator keeps its state, so batches can be chained.

    With compiled kernels (the extension of ``imuhal kernels build``, or numba: the ``fast``
    extra; see common/fast.py) the rows after alignment run in the estimator's compiled
    kernel where it has one; the results equal this loop's to 1e-12
    (``IMUHAL_KERNELS=python`` or ``IMUHAL_NO_JIT=1`` forces the pure-Python loop).
    """
    gyro = np.asarray(gyro_rad_s, dtype=float)
    n = gyro.shape[0]
    if gyro.shape != (n, 3):
        raise ValueError(f"gyro must be N x 3, got {gyro.shape}")
    accel = _optional(accel_m_s2, n, "accel")
    mag = _optional(mag_ut, n, "mag")
    if dt_s is None:
        dts = np.full(n, estimator.settings.sample_period_s)
    else:
        dts = np.broadcast_to(np.asarray(dt_s, dtype=float), (n,))
    out = np.full((n, 4), np.nan)
    if estimator._kernel_allowed():
        steps = update_rows(estimator, gyro, accel, mag, dts)
        if len(steps) == n:  # every row steps: the kernel writes the output in place
            estimator._step_rows(steps, diagnostics=False, out=out)
            return out
        q, emitted, _ = estimator._step_rows(steps, diagnostics=False)
        out[steps.index[emitted]] = q[emitted]
        return out
    # rows as plain float tuples and the "no sample" rows found once for the whole array:
    # per-row numpy indexing and isnan cost more than the filter step itself
    no_sample = [None] * n
    accel_rows: list[Any] = no_sample if accel is None else _rows(accel)
    mag_rows: list[Any] = no_sample if mag is None else _rows(mag)
    update = estimator.update
    for i, (g, a, m, dt) in enumerate(zip(gyro.tolist(), accel_rows, mag_rows, dts.tolist(),
                                          strict=True)):
        q = update(g, a, m, dt)  # type: ignore[assignment]  # update returns None only for a row it skips, tested before the store
        if q is not None:
            out[i] = q
    return out


def _rows(values: FloatArray) -> list[tuple[float, ...] | None]:
    """Each row as a tuple, None where any component is NaN ("no sample this step")."""
    missing = np.isnan(values).any(axis=1).tolist()
    return [None if gap else tuple(row) for row, gap in zip(values.tolist(), missing,  # type: ignore[arg-type]  # numpy's stubs type .tolist() of a bool array as bool
                                                             strict=True)]


def _optional(values: ArrayLike | None, n: int, what: str) -> FloatArray | None:
    if values is None:
        return None
    arr = np.asarray(values, dtype=float)
    if arr.shape != (n, 3):
        raise ValueError(f"{what} must be N x 3 like the gyro ({n} rows), got {arr.shape}")
    return arr
