"""Array entry points: run a variometer filter over recorded altitude / acceleration columns.

Row ``i`` of every output is the state after the step that consumed input row ``i``; this is
the call sequence of the conformance references (configure with the first altitude, then one
step per row, row 0 included), so a CSV of references can be compared row by row. With
compiled kernels (``vario/fast.py``: the extension of ``imuhal kernels build``, or numba) the
loops run compiled, equal to the Python loops to 1e-12; ``IMUHAL_KERNELS=python`` forces
Python.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from imuhal_filters.common import fast
from imuhal_filters.vario.baro_estimator import BaroVarioSettings
from imuhal_filters.vario.baro_kalman import BaroKalman2
from imuhal_filters.vario.fast import baro_rows, kf3_rows
from imuhal_filters.vario.kf3 import AVARIO_ACCEL_VARIANCE_DIVISOR, AVARIO_ACCEL_VARIANCE_RANGE
from imuhal_filters.vario.kf3_settings import CM_PER_M, VarioKf3Settings, configured_core


@dataclass(frozen=True)
class VarioBatchResult:
    altitude_m: NDArray[np.float64]
    climb_m_s: NDArray[np.float64]
    accel_bias_m_s2: NDArray[np.float64] | None
    """None for the barometer-only filter."""


def _columns(z_m: ArrayLike, dt_s: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    z = np.asarray(z_m, dtype=float).ravel()
    dt = np.broadcast_to(np.asarray(dt_s, dtype=float), z.shape)
    if z.size == 0:
        raise ValueError("no altitude samples")
    if np.any(dt <= 0) or not np.all(np.isfinite(dt)):
        raise ValueError("every dt_s must be a positive finite number of seconds")
    return z, dt


def run_batch(
    z_m: ArrayLike,
    accel_up_m_s2: ArrayLike,
    dt_s: ArrayLike,
    settings: VarioKf3Settings | dict[str, Any] | None = None,
) -> VarioBatchResult:
    """Run vario-kf3 over barometric altitude (m, up +) and the barometer-rate mean upward
    acceleration (m/s^2, gravity removed, bias included) with step lengths ``dt_s`` (s, a
    scalar or one per row). Returns altitude (m), climb (m/s) and accel bias (m/s^2) per row."""
    s = VarioKf3Settings.model_validate(settings or {})
    z, dt = _columns(z_m, dt_s)
    a = np.asarray(accel_up_m_s2, dtype=float).ravel()
    if a.shape != z.shape:
        raise ValueError(f"{a.size} accelerations for {z.size} altitudes")
    kf = configured_core(s, float(z[0]))
    out = np.empty((z.size, 3))
    if kf3_rows.available():
        ref = kf.reference
        variances = np.array([kf.z_meas_variance, kf.accel_variance, kf.bias_variance])
        lo, hi = AVARIO_ACCEL_VARIANCE_RANGE
        kf3_rows(kf.x, kf.P, variances, ref.semi_implicit, ref.adaptive_accel_variance,
                 lo, hi, AVARIO_ACCEL_VARIANCE_DIVISOR, z * CM_PER_M, a * CM_PER_M,
                 fast.c_array(dt), out)
    else:
        for i in range(z.size):
            kf.step(z[i] * CM_PER_M, a[i] * CM_PER_M, float(dt[i]))
            out[i] = kf.x
    out /= CM_PER_M
    return VarioBatchResult(out[:, 0], out[:, 1], out[:, 2])


def run_baro_batch(
    z_m: ArrayLike,
    dt_s: ArrayLike,
    settings: BaroVarioSettings | dict[str, Any] | None = None,
) -> VarioBatchResult:
    """Run baro-vario over barometric altitude (m, up +) with step lengths ``dt_s`` (s).

    The filter starts at the first altitude with zero climb, then predicts and updates on
    every row (row 0 included, so row 0 equals its measurement blended with itself)."""
    s = BaroVarioSettings.model_validate(settings or {})
    z, dt = _columns(z_m, dt_s)
    kf = BaroKalman2(accel_var=s.accel_noise_m_s2**2, meas_var=s.altitude_noise_m**2)
    kf.initialise(float(z[0]), 0.0, s.altitude_noise_m**2, s.initial_climb_sigma_m_s**2)
    out = np.empty((z.size, 2))
    if baro_rows.available():
        state = np.array([kf.z, kf.v, kf.pzz, kf.pzv, kf.pvv])
        baro_rows(state, kf.accel_var, kf.meas_var, fast.c_array(z), fast.c_array(dt), out)
    else:
        for i in range(z.size):
            kf.predict(float(dt[i]))
            kf.update(float(z[i]))
            out[i] = (kf.z, kf.v)
    return VarioBatchResult(out[:, 0], out[:, 1], None)
