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


def _same_instants(t_g, t, values, full_scale):
    """A block whose frames stand at the gyro frames' instants, each instant once, every
    value within +-``full_scale`` (NaN fails): ``common/rows.py``'s common case, in which
    each step takes its own instant's frame and nothing is held, dropped or stale."""
    m = t_g.shape[0]
    if t.shape[0] != m:
        return False
    for i in range(m):
        if t[i] != t_g[i] or (i > 0 and not t_g[i] > t_g[i - 1]):
            return False
        for k in range(3):
            if not abs(values[i, k]) <= full_scale:
                return False
    return True


same_instants = jit(_same_instants)
"""A helper of ``madgwick_block``."""


def _block_case(t_g, gyro, t_a, accel, t_m, mag, mag_block, keep_mag, gyro_fs, accel_fs):
    """The blocks are ``block_rows``'s common case (see ``_madgwick_block``)."""
    if t_g.shape[0] == 0 or not same_instants(t_g, t_g, gyro, gyro_fs) \
            or not same_instants(t_g, t_a, accel, accel_fs):
        return False
    if not mag_block:
        return True
    if keep_mag:
        return same_instants(t_g, t_m, mag, 1.7976931348623157e308)
    for i in range(mag.shape[0]):  # a non-finite one is counted by block_rows
        for k in range(3):
            if not abs(mag[i, k]) <= 1.7976931348623157e308:
                return False
    return True


block_case = jit(_block_case)
"""A helper of ``madgwick_block``."""


def _step_lengths(t_g, last_t, has_last, nominal_dt, dt_from_ts, max_dt, dts):
    """``rows._step_lengths`` into ``dts``; returns the fallbacks to nominal it counts."""
    fallbacks = 0
    for i in range(t_g.shape[0]):
        if not dt_from_ts or (i == 0 and not has_last):
            dts[i] = nominal_dt
            continue
        dt = (t_g[i] - (last_t if i == 0 else t_g[i - 1])) * 1e-9
        if dt > 0.0 and dt <= max_dt:
            dts[i] = dt
        else:
            dts[i] = nominal_dt
            fallbacks += 1
    return fallbacks


step_lengths = jit(_step_lengths)
"""A helper of ``madgwick_block``."""


def _nominal_fused(gyro, accel, speed):
    """``turn.nominal_rows`` (``speed`` NaN: the rows as they are), a new array."""
    fused = np.empty(accel.shape)
    for i in range(accel.shape[0]):
        fused[i, 0], fused[i, 1], fused[i, 2] = accel[i, 0], accel[i, 1], accel[i, 2]
        if not math.isnan(speed):
            ky = gyro[i, 2] * speed
            kz = -gyro[i, 1] * speed
            if ky != 0.0 or kz != 0.0:
                fused[i, 1] = accel[i, 1] - ky
                fused[i, 2] = accel[i, 2] - kz
    return fused


nominal_fused = jit(_nominal_fused)
"""A helper of ``madgwick_block``."""


def _mag_rows(t_g, mag, mag_block, keep_mag, held_mag, held_mag_t, has_held_mag, max_age):
    """The magnetometer row of each step (NaN: none) as ``rows._held_at`` resolves it in
    the common case, and the steps whose held frame was stale."""
    m = t_g.shape[0]
    rows = np.empty((m, 3))
    stale = 0
    for i in range(m):
        if mag_block and keep_mag:
            rows[i, 0], rows[i, 1], rows[i, 2] = mag[i, 0], mag[i, 1], mag[i, 2]
        elif not mag_block and keep_mag and has_held_mag and not (
                (t_g[i] - held_mag_t) * 1e-9 > max_age):  # NaN max_age: never stale
            rows[i, 0], rows[i, 1], rows[i, 2] = held_mag[0], held_mag[1], held_mag[2]
        else:
            if not mag_block and keep_mag and has_held_mag:
                stale += 1
            rows[i, 0] = rows[i, 1] = rows[i, 2] = np.nan
    return rows, stale


mag_rows_kernel = jit(_mag_rows)
"""A helper of ``madgwick_block``."""


def _madgwick_block(q_in, t_g, gyro, t_a, accel, t_m, mag, mag_block, keep_mag, held_mag,
                    held_mag_t, has_held_mag, max_age, last_t, has_last, gyro_fs, accel_fs,
                    nominal_dt, dt_from_ts, max_dt, speed,
                    beta, gate_lo, gate_hi, soft_width, paper, use_mag, turn_on, turn_sum,
                    out, diag, dts, lin, rest, rest_params):
    """A FIFO read's frames (``AhrsEstimator.update_blocks`` once aligned) in one call: the
    bookkeeping of ``common/rows.py``'s ``block_rows`` for its common case (every gyro frame
    within full scale, an accelerometer frame at each gyro frame's instant and within its
    full scale, the magnetometer's likewise when kept), the step lengths from the gyro times
    (``nominal_dt`` for a gap outside (0, ``max_dt``] and for the first step without
    ``has_last``), the turn compensation by the nominal airspeed ``speed`` (NaN: none) as
    ``turn.nominal_rows`` computes it, the kept magnetometer frame ``held_mag`` (taken at
    ``held_mag_t``; ``has_held_mag`` False: none) for every step when there is no
    magnetometer block, unless older than ``max_age`` s (NaN: no limit; counted stale),
    the row loop of ``madgwick_rows``, and into ``lin``
    the gravity-compensated acceleration (NED) of the measured specific force at each new
    attitude. ``dts`` gets the step lengths. Returns the final quaternion, the turn-rate sum,
    the steps with the gate closed, the step lengths that fell back to nominal, the stale
    magnetometer steps, and True; or False with nothing written or changed (not the common
    case: ``block_rows`` decides)."""
    q = np.empty(4)
    if not block_case(t_g, gyro, t_a, accel, t_m, mag, mag_block, keep_mag, gyro_fs,
                      accel_fs):
        return q, turn_sum, 0, 0, 0, False
    fallbacks = step_lengths(t_g, last_t, has_last, nominal_dt, dt_from_ts, max_dt, dts)
    mag_rows, stale = mag_rows_kernel(t_g, mag, mag_block, keep_mag, held_mag, held_mag_t,
                                      has_held_mag, max_age)
    state, turn_sum, closed = madgwick_step_rows(
        (q_in[0], q_in[1], q_in[2], q_in[3]),
        (beta, gate_lo, gate_hi, soft_width, paper), gyro, nominal_fused(gyro, accel, speed),
        mag_rows, dts, use_mag, turn_on, turn_sum, out, diag, rest, rest_params)
    for i in range(t_g.shape[0]):
        lin[i, 0], lin[i, 1], lin[i, 2] = linear_accel_ned(
            out[i, 0], out[i, 1], out[i, 2], out[i, 3], accel[i, 0], accel[i, 1], accel[i, 2])
    q[0], q[1], q[2], q[3] = state[0], state[1], state[2], state[3]
    return q, turn_sum, closed, fallbacks, stale, True


madgwick_block = jit(
    _madgwick_block, returns="Tuple((f8[::1], f8, i8, i8, i8, b1))", q_in="f8[::1]",
    t_g="i8[::1]", gyro="f8[:, ::1]", t_a="i8[::1]", accel="f8[:, ::1]", t_m="i8[::1]",
    mag="f8[:, ::1]", mag_block="b1", keep_mag="b1", held_mag="f8[::1]", held_mag_t="i8",
    has_held_mag="b1", max_age="f8", last_t="i8", has_last="b1",
    gyro_fs="f8", accel_fs="f8", nominal_dt="f8", dt_from_ts="b1", max_dt="f8", speed="f8",
    beta="f8", gate_lo="f8", gate_hi="f8", soft_width="f8", paper="b1", use_mag="b1",
    turn_on="b1", turn_sum="f8", out="f8[:, ::1]", diag="f8[:, ::1]", dts="f8[::1]",
    lin="f8[:, ::1]", rest="f8[::1]", rest_params="f8[::1]")
"""The block step (see common/fast.py: the extension, or numba on the first call)."""
