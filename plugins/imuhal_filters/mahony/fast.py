"""The Mahony batch step loop as one compiled kernel (``fast`` extra; see common/fast.py).

Row by row and in the same order of operations as ``MahonyEstimator._step`` and
``mahony_step``, once the attitude is aligned: the PI feedback here, the row loop (with the
nominal-free turn bookkeeping) and the hard and soft accelerometer gates shared with every
AHRS (``common/fast_ahrs.py``). The rows are resolved before by ``common/rows.py``.
"""

from __future__ import annotations

import math

import numpy as np

from imuhal_filters.common.fast import jit, per_sample_kernel
from imuhal_filters.common.fast_ahrs import accel_gate_kernel, ahrs_rows
from imuhal_filters.common.fast_frames import linear_accel_ned


def _mahony_rows(q_in, integral_in, gyro, accel, mag, dts, kp, ki, gate_lo, gate_hi,
                 soft_width, use_mag, turn_on, turn_sum, out, diag, rest, rest_params):
    """One step per row: the shared row loop (``common/fast_ahrs.py``) with the Mahony step
    (``out``, ``diag`` and the rest detector's state ``rest`` as it fills them, ``diag`` of
    10 columns: the integral's gyro bias last).
    Returns the final quaternion, integral feedback, turn-rate sum and steps with the gate
    closed."""
    state, turn_sum, closed = mahony_step_rows(
        (q_in[0], q_in[1], q_in[2], q_in[3], integral_in[0], integral_in[1], integral_in[2]),
        (kp, ki, gate_lo, gate_hi, soft_width), gyro, accel, mag, dts, use_mag, turn_on,
        turn_sum, out, diag, rest, rest_params)
    return (np.array([state[0], state[1], state[2], state[3]]),
            np.array([state[4], state[5], state[6]]), turn_sum, closed)


mahony_rows = jit(
    _mahony_rows, returns="Tuple((f8[::1], f8[::1], f8, i8))", q_in="f8[::1]",
    integral_in="f8[::1]", gyro="f8[:, ::1]", accel="f8[:, ::1]", mag="f8[:, ::1]",
    dts="f8[::1]", kp="f8", ki="f8", gate_lo="f8", gate_hi="f8", soft_width="f8",
    use_mag="b1", turn_on="b1", turn_sum="f8", out="f8[:, ::1]", diag="f8[:, ::1]",
    rest="f8[::1]", rest_params="f8[::1]")
"""The compiled kernel (see common/fast.py: the extension, or numba on the first call)."""


def _mahony_step(state, params, gx, gy, gz, have_a, ax, ay, az, have_m, mx0, my0, mz0, dt,
                 at_rest):
    """One step: ``MahonyEstimator._step`` with ``mahony_step`` on scalars, in the same order
    of operations; a step of the shared row loop (``state`` the quaternion and
    the integral feedback, ``params`` (kp, ki, gate_lo, gate_hi, soft_width)). ``a`` is the
    gravity-positive reading in g (``have_a`` False: none), ``m`` the magnetometer
    (``have_m`` False: none or not used). Returns the new quaternion and integral, whether
    the gate was open, the soft-gate weight and the gyro bias (minus the integral)."""
    q0, q1, q2, q3, ix, iy, iz = state
    kp, ki, gate_lo, gate_hi, soft_width = params
    # at rest the reading is gravity: no soft gate (weight 1)
    gate_open, weight = accel_gate_kernel(have_a, ax, ay, az, q0, q1, q2, q3, gate_lo,
                                         gate_hi, 0.0 if at_rest else soft_width)
    kpw, kiw = kp * weight, ki * weight
    if gate_open:
        n = math.sqrt(ax * ax + ay * ay + az * az)
        if n != 0.0 and math.isfinite(n):
            a0, a1, a2 = ax / n, ay / n, az / n
            hvx = q1 * q3 - q0 * q2
            hvy = q0 * q1 + q2 * q3
            hvz = q0 * q0 - 0.5 + q3 * q3
            ex = a1 * hvz - a2 * hvy
            ey = a2 * hvx - a0 * hvz
            ez = a0 * hvy - a1 * hvx
            if have_m:
                nm = math.sqrt(mx0 * mx0 + my0 * my0 + mz0 * mz0)
                if nm != 0.0 and math.isfinite(nm):
                    mx, my, mz = mx0 / nm, my0 / nm, mz0 / nm
                    q11, q22, q33 = q1 * q1, q2 * q2, q3 * q3
                    hx = 2.0 * (mx * (0.5 - q22 - q33) + my * (q1 * q2 - q0 * q3)
                                + mz * (q1 * q3 + q0 * q2))
                    hy = 2.0 * (mx * (q1 * q2 + q0 * q3) + my * (0.5 - q11 - q33)
                                + mz * (q2 * q3 - q0 * q1))
                    bx = math.sqrt(hx * hx + hy * hy)
                    bz = 2.0 * (mx * (q1 * q3 - q0 * q2) + my * (q2 * q3 + q0 * q1)
                                + mz * (0.5 - q11 - q22))
                    hwx = bx * (0.5 - q22 - q33) + bz * (q1 * q3 - q0 * q2)
                    hwy = bx * (q1 * q2 - q0 * q3) + bz * (q0 * q1 + q2 * q3)
                    hwz = bx * (q0 * q2 + q1 * q3) + bz * (0.5 - q11 - q22)
                    ex += my * hwz - mz * hwy
                    ey += mz * hwx - mx * hwz
                    ez += mx * hwy - my * hwx
            if kiw > 0.0:
                ix, iy, iz = (ix + 2.0 * kiw * ex * dt, iy + 2.0 * kiw * ey * dt,
                              iz + 2.0 * kiw * ez * dt)
                gx, gy, gz = gx + ix, gy + iy, gz + iz
            else:
                ix, iy, iz = 0.0, 0.0, 0.0
            gx, gy, gz = gx + 2.0 * kpw * ex, gy + 2.0 * kpw * ey, gz + 2.0 * kpw * ez
    h = 0.5 * dt
    gx, gy, gz = gx * h, gy * h, gz * h
    w = q0 + (-q1 * gx - q2 * gy - q3 * gz)
    x = q1 + (q0 * gx + q2 * gz - q3 * gy)
    y = q2 + (q0 * gy - q1 * gz + q3 * gx)
    z = q3 + (q0 * gz + q1 * gy - q2 * gx)
    r = 1.0 / math.sqrt(w * w + x * x + y * y + z * z)
    return (w * r, x * r, y * r, z * r, ix, iy, iz), gate_open, weight, (-ix, -iy, -iz)


mahony_step_kernel = jit(_mahony_step)
"""The step as a helper kernel: compiled into ``mahony_rows`` and ``mahony_sample``."""

mahony_step_rows = ahrs_rows(mahony_step_kernel)
"""The shared row loop with this step (a helper kernel of ``mahony_rows``)."""


def _mahony_sample(q0, q1, q2, q3, ix, iy, iz, gx, gy, gz, have_a, ax, ay, az, have_m, mx0,
                   my0, mz0, kp, ki, gate_lo, gate_hi, soft_width, dt, at_rest, fx, fy, fz):
    """The step called from Python once per sample (``process()``; see ``madgwick_sample``:
    ``g`` less the bias learned at rest, ``at_rest`` the caller's rest detector's verdict),
    with the gravity-compensated acceleration in NED last."""
    (w, x, y, z, ix, iy, iz), gate_open, weight, _ = mahony_step_kernel(
        (q0, q1, q2, q3, ix, iy, iz), (kp, ki, gate_lo, gate_hi, soft_width), gx, gy, gz,
        have_a, ax, ay, az, have_m, mx0, my0, mz0, dt, at_rest)
    lx, ly, lz = linear_accel_ned(w, x, y, z, fx, fy, fz)
    return w, x, y, z, ix, iy, iz, gate_open, weight, lx, ly, lz


mahony_sample = per_sample_kernel(jit(
    _mahony_sample, returns="Tuple((f8, f8, f8, f8, f8, f8, f8, b1, f8, f8, f8, f8))",
    q0="f8", q1="f8", q2="f8", q3="f8", ix="f8", iy="f8", iz="f8", gx="f8", gy="f8", gz="f8",
    have_a="b1",
    ax="f8", ay="f8", az="f8", have_m="b1", mx0="f8", my0="f8", mz0="f8", kp="f8", ki="f8",
    gate_lo="f8", gate_hi="f8", soft_width="f8", dt="f8", at_rest="b1", fx="f8", fy="f8",
    fz="f8"))
"""The per-sample kernel (used per sample only on the AOT extension: ``Kernel.per_sample``)."""
