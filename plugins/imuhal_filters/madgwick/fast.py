"""The Madgwick batch step loop as one compiled kernel (``fast`` extra; see common/fast.py).

It repeats, row by row and in the same order of operations, what
``MadgwickEstimator._step`` and ``madgwick_step`` (exact 1/sqrt) do once the attitude is
aligned: the gradient step here, the row loop (with the nominal-free turn bookkeeping) and
the hard and soft accelerometer gates shared with every AHRS (``common/fast_ahrs.py``).
Which rows step and with which accel and mag (full scales, held and stale samples, step
lengths) is decided before, for every AHRS alike, by ``common/rows.py``.
Anything it does not cover (fast32 square root, turn compensation with a speed source, rows
before alignment) stays on the pure-Python path.
"""

from __future__ import annotations

import math

import numpy as np

from imuhal_filters.common.fast import jit, per_sample_kernel
from imuhal_filters.common.fast_ahrs import NO_BIAS, accel_gate_kernel, ahrs_rows
from imuhal_filters.common.fast_frames import linear_accel_ned


def _madgwick_rows(q_in, gyro, accel, mag, dts, beta, gate_lo, gate_hi, soft_width, paper,
                   use_mag, turn_on, turn_sum, out, diag, rest, rest_params):
    """One step per row: the shared row loop (``common/fast_ahrs.py``) with the Madgwick
    step (``out``, ``diag`` and the rest detector's state ``rest`` as it fills them,
    ``diag`` of 7 columns). Returns the final quaternion, the turn-rate sum (turn
    bookkeeping) and the number of steps with the gate closed."""
    state, turn_sum, closed = madgwick_step_rows(
        (q_in[0], q_in[1], q_in[2], q_in[3]),
        (beta, gate_lo, gate_hi, soft_width, paper), gyro, accel, mag, dts, use_mag, turn_on,
        turn_sum, out, diag, rest, rest_params)
    return np.array([state[0], state[1], state[2], state[3]]), turn_sum, closed


madgwick_rows = jit(
    _madgwick_rows, returns="Tuple((f8[::1], f8, i8))", q_in="f8[::1]", gyro="f8[:, ::1]",
    accel="f8[:, ::1]", mag="f8[:, ::1]", dts="f8[::1]", beta="f8", gate_lo="f8",
    gate_hi="f8", soft_width="f8", paper="b1", use_mag="b1", turn_on="b1", turn_sum="f8",
    out="f8[:, ::1]", diag="f8[:, ::1]", rest="f8[::1]", rest_params="f8[::1]")
"""The compiled kernel (see common/fast.py: the extension, or numba on the first call)."""


def _madgwick_step(state, params, gx, gy, gz, have_a, ax, ay, az, have_m, mx0, my0, mz0, dt,
                   at_rest):
    """One step: ``MadgwickEstimator._step`` with ``madgwick_step`` (exact 1/sqrt) on
    scalars, in the same order of operations; a step of the shared row loop
    (``state`` the quaternion, ``params`` (beta, gate_lo, gate_hi, soft_width, paper)).
    ``a`` is the gravity-positive reading in g (``have_a`` False: none), ``m`` the
    magnetometer (``have_m`` False: none or not used). Returns the new quaternion, whether
    the gate was open, the soft-gate weight and no gyro bias."""
    q0, q1, q2, q3 = state
    beta, gate_lo, gate_hi, soft_width, paper = params
    # at rest the reading is gravity: no soft gate (weight 1)
    gate_open, weight = accel_gate_kernel(have_a, ax, ay, az, q0, q1, q2, q3, gate_lo,
                                         gate_hi, 0.0 if at_rest else soft_width)
    b = beta * weight
    d0 = 0.5 * (-q1 * gx - q2 * gy - q3 * gz)
    d1 = 0.5 * (q0 * gx + q2 * gz - q3 * gy)
    d2 = 0.5 * (q0 * gy - q1 * gz + q3 * gx)
    d3 = 0.5 * (q0 * gz + q1 * gy - q2 * gx)
    if gate_open:
        n2 = ax * ax + ay * ay + az * az
        if n2 != 0.0:
            r = 1.0 / math.sqrt(n2)
            a0, a1, a2 = ax * r, ay * r, az * r
            f1 = 2.0 * (q1 * q3 - q0 * q2) - a0
            f2 = 2.0 * (q0 * q1 + q2 * q3) - a1
            f3 = 2.0 * (0.5 - q1 * q1 - q2 * q2) - a2
            s0 = -2.0 * q2 * f1 + 2.0 * q1 * f2
            s1 = 2.0 * q3 * f1 + 2.0 * q0 * f2 - 4.0 * q1 * f3
            s2 = -2.0 * q0 * f1 + 2.0 * q3 * f2 - 4.0 * q2 * f3
            s3 = 2.0 * q1 * f1 + 2.0 * q2 * f2
            if have_m:
                m2 = mx0 * mx0 + my0 * my0 + mz0 * mz0
                if m2 != 0.0:
                    r = 1.0 / math.sqrt(m2)
                    mx, my, mz = mx0 * r, my0 * r, mz0 * r
                    q00, q11, q22, q33 = q0 * q0, q1 * q1, q2 * q2, q3 * q3
                    hx = (mx * (q00 + q11 - q22 - q33) + 2.0 * my * (q1 * q2 - q0 * q3)
                          + 2.0 * mz * (q1 * q3 + q0 * q2))
                    hy = (2.0 * mx * (q1 * q2 + q0 * q3) + my * (q00 - q11 + q22 - q33)
                          + 2.0 * mz * (q2 * q3 - q0 * q1))
                    hz = (2.0 * mx * (q1 * q3 - q0 * q2) + 2.0 * my * (q2 * q3 + q0 * q1)
                          + mz * (q00 - q11 - q22 + q33))
                    scale = 2.0 if paper else 1.0
                    bx2 = scale * math.sqrt(hx * hx + hy * hy)
                    bz2 = scale * hz
                    f4 = bx2 * (0.5 - q22 - q33) + bz2 * (q1 * q3 - q0 * q2) - mx
                    f5 = bx2 * (q1 * q2 - q0 * q3) + bz2 * (q0 * q1 + q2 * q3) - my
                    f6 = bx2 * (q0 * q2 + q1 * q3) + bz2 * (0.5 - q11 - q22) - mz
                    g0 = -bz2 * q2 * f4 + (-bx2 * q3 + bz2 * q1) * f5 + bx2 * q2 * f6
                    g1 = (bz2 * q3 * f4 + (bx2 * q2 + bz2 * q0) * f5
                          + (bx2 * q3 - 2.0 * bz2 * q1) * f6)
                    g2 = ((-2.0 * bx2 * q2 - bz2 * q0) * f4 + (bx2 * q1 + bz2 * q3) * f5
                          + (bx2 * q0 - 2.0 * bz2 * q2) * f6)
                    g3 = ((-2.0 * bx2 * q3 + bz2 * q1) * f4 + (-bx2 * q0 + bz2 * q2) * f5
                          + bx2 * q1 * f6)
                    s0, s1, s2, s3 = s0 + g0, s1 + g1, s2 + g2, s3 + g3
            n2 = s0 * s0 + s1 * s1 + s2 * s2 + s3 * s3
            if n2 > 0.0:
                kk = b * (1.0 / math.sqrt(n2))
                d0, d1, d2, d3 = d0 - kk * s0, d1 - kk * s1, d2 - kk * s2, d3 - kk * s3
    w, x, y, z = q0 + d0 * dt, q1 + d1 * dt, q2 + d2 * dt, q3 + d3 * dt
    r = 1.0 / math.sqrt(w * w + x * x + y * y + z * z)
    return (w * r, x * r, y * r, z * r), gate_open, weight, NO_BIAS


madgwick_step_kernel = jit(_madgwick_step)
"""The step as a helper kernel: compiled into ``madgwick_rows`` and ``madgwick_sample``."""

madgwick_step_rows = ahrs_rows(madgwick_step_kernel)
"""The shared row loop with this step (a helper kernel of ``madgwick_rows``)."""


def _madgwick_sample(q0, q1, q2, q3, gx, gy, gz, have_a, ax, ay, az, have_m, mx0, my0, mz0,
                     beta, gate_lo, gate_hi, soft_width, paper, dt, at_rest, fx, fy, fz):
    """The step called from Python once per sample (``process()``): scalars in, a tuple
    out, nothing allocated, so a call to the AOT extension's function costs about 0.3 us
    (numba's dispatcher about 0.7-1.7 us). Also returns the gravity-compensated
    acceleration in NED for the measured specific force ``f`` (m/s^2) at the new attitude
    (what the estimate carries; meaningless without an accelerometer). The rest detector
    runs in the caller: ``g`` is the gyro less the bias learned at rest, ``at_rest`` its
    verdict."""
    (w, x, y, z), gate_open, weight, _ = madgwick_step_kernel(
        (q0, q1, q2, q3), (beta, gate_lo, gate_hi, soft_width, paper), gx, gy, gz, have_a, ax,
        ay, az, have_m, mx0, my0, mz0, dt, at_rest)
    lx, ly, lz = linear_accel_ned(w, x, y, z, fx, fy, fz)
    return w, x, y, z, gate_open, weight, lx, ly, lz


madgwick_sample = per_sample_kernel(jit(
    _madgwick_sample, returns="Tuple((f8, f8, f8, f8, b1, f8, f8, f8, f8))", q0="f8",
    q1="f8", q2="f8", q3="f8", gx="f8", gy="f8", gz="f8", have_a="b1", ax="f8", ay="f8",
    az="f8", have_m="b1",
    mx0="f8", my0="f8", mz0="f8", beta="f8", gate_lo="f8", gate_hi="f8", soft_width="f8",
    paper="b1", dt="f8", at_rest="b1", fx="f8", fy="f8", fz="f8"))
"""The per-sample kernel (see common/fast.py: used per sample only on the AOT extension,
:meth:`~imuhal_filters.common.fast.Kernel.per_sample`)."""
