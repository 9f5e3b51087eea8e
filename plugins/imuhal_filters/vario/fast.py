"""The variometer batch loops as compiled kernels (``fast`` extra; see common/fast.py).

Row by row and in the same order of operations as ``Kalman3.step`` (predict, then update,
with the mode's prediction variant and adaptive variance) and as ``BaroKalman2.predict`` then
``update``; the 3 x 3 products are written out in numpy's order (row times column, terms
summed left to right). ``vario/batch.py`` selects them when they run compiled (see
common/fast.py).
"""

from __future__ import annotations

import numpy as np

from imuhal_filters.common.fast import jit


def _kf3_rows(x, P, variances, semi_implicit, adaptive, var_lo, var_hi, var_div, z_cm, a_cm,
              dts, out):
    """``Kalman3.step(z_cm[i], a_cm[i], dts[i])`` per row; ``x`` (3), ``P`` (3 x 3) and
    ``variances`` (z, accel, bias) are updated in place; ``out[i]`` is x after row i (cm)."""
    F = np.eye(3)
    Q = np.zeros((3, 3))
    T = np.empty((3, 3))
    Pn = np.empty((3, 3))
    k = np.empty(3)
    r_z, sa2, sb2 = variances[0], variances[1], variances[2]
    for i in range(z_cm.shape[0]):
        dt = dts[i]
        z, v, b = x[0], x[1], x[2]
        accel = a_cm[i] - b
        if semi_implicit:
            v = v + accel * dt
            z = z + v * dt
        else:
            z = z + v * dt
            v = v + accel * dt
        x[0], x[1], x[2] = z, v, b
        if adaptive:
            sa2 = min(max(abs(accel) / var_div, var_lo), var_hi)
        dt2 = dt * dt
        F[0, 1], F[0, 2], F[1, 2] = dt, -0.5 * dt2, -dt
        Q[0, 0] = 0.25 * dt2 * dt2 * sa2
        Q[0, 1] = Q[1, 0] = 0.5 * dt2 * dt * sa2
        Q[1, 1] = dt2 * sa2
        Q[2, 2] = sb2
        for r in range(3):
            for c in range(3):
                T[r, c] = F[r, 0] * P[0, c] + F[r, 1] * P[1, c] + F[r, 2] * P[2, c]
        for r in range(3):
            for c in range(3):
                P[r, c] = T[r, 0] * F[c, 0] + T[r, 1] * F[c, 1] + T[r, 2] * F[c, 2] + Q[r, c]
        # update
        innovation = z_cm[i] - x[0]
        s = P[0, 0] + r_z
        for r in range(3):
            k[r] = P[r, 0] / s
        for r in range(3):
            x[r] = x[r] + k[r] * innovation
        for r in range(3):
            for c in range(3):
                Pn[r, c] = P[r, c] - k[r] * P[0, c]
        for r in range(3):
            for c in range(3):
                P[r, c] = 0.5 * (Pn[r, c] + Pn[c, r])
        out[i, 0], out[i, 1], out[i, 2] = x[0], x[1], x[2]
    variances[1] = sa2


kf3_rows = jit(
    _kf3_rows, returns="none", x="f8[::1]", P="f8[:, ::1]", variances="f8[::1]",
    semi_implicit="b1", adaptive="b1", var_lo="f8", var_hi="f8", var_div="f8",
    z_cm="f8[::1]", a_cm="f8[::1]", dts="f8[::1]", out="f8[:, ::1]")


def _baro_rows(state, accel_var, meas_var, z_m, dts, out):
    """``BaroKalman2.predict(dts[i])`` then ``update(z_m[i])`` per row; ``state`` = z, v,
    pzz, pzv, pvv in and out; ``out[i]`` = (z, v) after row i."""
    z, v, pzz, pzv, pvv = state[0], state[1], state[2], state[3], state[4]
    q = accel_var
    for i in range(z_m.shape[0]):
        dt = dts[i]
        z += v * dt
        dt2 = dt * dt
        pzz, pzv, pvv = (pzz + 2.0 * dt * pzv + dt2 * pvv + q * dt2 * dt2 / 4.0,
                         pzv + dt * pvv + q * dt2 * dt / 2.0, pvv + q * dt2)
        innovation = z_m[i] - z
        s = pzz + meas_var
        kz = pzz / s
        kv = pzv / s
        z += kz * innovation
        v += kv * innovation
        pzz, pzv, pvv = pzz - kz * pzz, pzv - kz * pzv, pvv - kv * pzv
        out[i, 0], out[i, 1] = z, v
    state[0], state[1], state[2], state[3], state[4] = z, v, pzz, pzv, pvv


baro_rows = jit(_baro_rows, returns="none", state="f8[::1]", accel_var="f8",
               meas_var="f8", z_m="f8[::1]", dts="f8[::1]", out="f8[:, ::1]")
