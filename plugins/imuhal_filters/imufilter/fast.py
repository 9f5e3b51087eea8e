"""The imuFilter step loop as one compiled kernel (``fast`` extra; see common/fast.py).

Row by row and in the same order of operations as ``ImuFilterEstimator._step`` once the
filter is set up: ``gyro_step`` without an accelerometer, otherwise ``imufilter_step`` (the
accelerometer band's gain and variance, the correction towards the accelerometer's down) and,
when on, ``velocity_step``. The rows are resolved before by ``common/rows.py``. The helpers
below repeat common/quat.py for the kernel (numba compiles them with it); they live here, not
in a shared module, because numba's on-disk cache of a kernel does not notice a change to a
helper in another file.
"""

from __future__ import annotations

import math

import numpy as np

from imuhal_filters.common.fast import jit, per_sample_kernel
from imuhal_filters.common.fast_ahrs import rest_update_kernel
from imuhal_filters.common.fast_frames import linear_accel_ned

_G = 9.80665  # STANDARD_GRAVITY_M_S2


def _to_global(w, x, y, z, vx, vy, vz):
    """common.quat.to_global: q v q* on plain floats."""
    tx = 2.0 * (y * vz - z * vy)
    ty = 2.0 * (z * vx - x * vz)
    tz = 2.0 * (x * vy - y * vx)
    return (vx + w * tx + (y * tz - z * ty), vy + w * ty + (z * tx - x * tz),
            vz + w * tz + (x * ty - y * tx))


to_global = jit(_to_global)


def _small_step(w, x, y, z, dx, dy, dz):
    """normalized(multiply(q, _small_rotation(d))), as imufilter/core.py composes them."""
    vx, vy, vz = 0.5 * dx, 0.5 * dy, 0.5 * dz
    rw = 1.0 - 0.5 * (vx * vx + vy * vy + vz * vz)
    pw = w * rw - x * vx - y * vy - z * vz
    px = w * vx + x * rw + y * vz - z * vy
    py = w * vy - x * vz + y * rw + z * vx
    pz = w * vz + x * vy - y * vx + z * rw
    inv = 1.0 / math.sqrt(pw * pw + px * px + py * py + pz * pz)
    return pw * inv, px * inv, py * inv, pz * inv


small_step = jit(_small_step)


def _imufilter_step(w, x, y, z, var, gain, gx, gy, gz, have_a, ax, ay, az, dt, alpha,
                    sd_acc_g, velocity_on, var_a, var_comb, v0, v1, v2, m0, m1, m2, l0, l1, l2,
                    var_vel, var_acc, tg0, tg1, tg2, at_rest):
    """One step: ``gyro_step`` without an accelerometer, else ``imufilter_step`` (gain 1
    ``at_rest``) and, when on, ``velocity_step``, on scalars in the same order of operations;
    ``a`` gravity-positive in g, ``var_a`` and ``var_comb`` the velocity filter's constant
    variances. Returns the new quaternion, variance, gain, velocity (3), accel mean (3), last
    accel (3), var_vel and var_acc."""
    if not have_a:
        w, x, y, z = small_step(w, x, y, z, gx * dt, gy * dt, gz * dt)
        return (w, x, y, z, var, gain, v0, v1, v2, m0, m1, m2, l0, l1, l2, var_vel, var_acc)
    # accel_kalman_gain
    ex, ey, ez = to_global(w, x, y, z, ax, ay, az)
    ez -= 1.0
    error = ex * ex + ey * ey + ez * ez
    gain = 1.0 / (1.0 + var / (sd_acc_g * sd_acc_g))
    var = error + var * gain
    if at_rest:
        gain = 1.0
    n = math.sqrt(ax * ax + ay * ay + az * az)
    ux, uy, uz = ax / n, ay / n, az / n
    dx, dy, dz = to_global(w, -x, -y, -z, 0.0, 0.0, 1.0)  # to_local(q, DOWN)
    vex, vey, vez = uy * dz - uz * dy, uz * dx - ux * dz, ux * dy - uy * dx
    kk = gain * alpha * dt
    w, x, y, z = small_step(w, x, y, z, gx * dt + vex * kk, gy * dt + vey * kk,
                            gz * dt + vez * kk)
    if velocity_on:
        # velocity_step with the specific force back in m/s^2
        fx, fy, fz = ax * -_G, ay * -_G, az * -_G
        bx, by, bz = to_global(w, -x, -y, -z, v0, v1, v2)  # to_local(q, v)
        cx, cy, cz = by * gz - bz * gy, bz * gx - bx * gz, bx * gy - by * gx
        nx, ny, nz = to_global(w, x, y, z, fx - cx, fy - cy, fz - cz)
        a0, a1, a2 = nx - m0, ny - m1, nz + _G - m2
        gain_acc = var_a / (var_a + var_acc)
        var_acc = a0 * a0 + a1 * a1 + a2 * a2 + gain_acc * var_acc
        m0, m1, m2 = m0 + a0 * gain_acc, m1 + a1 * gain_acc, m2 + a2 * gain_acc
        d0, d1, d2 = tg0 - v0, tg1 - v1, tg2 - v2
        gain_vel = var_comb / (var_comb + var_vel * var_acc)
        var_vel = d0 * d0 + d1 * d1 + d2 * d2 + gain_vel * var_vel
        h = 0.5 * dt
        v0 = v0 + (a0 + l0) * h + d0 * gain_vel
        v1 = v1 + (a1 + l1) * h + d1 * gain_vel
        v2 = v2 + (a2 + l2) * h + d2 * gain_vel
        l0, l1, l2 = a0, a1, a2
    return (w, x, y, z, var, gain, v0, v1, v2, m0, m1, m2, l0, l1, l2, var_vel, var_acc)


imufilter_step_kernel = jit(_imufilter_step)
"""The step as a helper kernel: compiled into ``imufilter_rows`` and ``imufilter_sample``."""


def _imufilter_rows(state, gyro, accel, dts, alpha, sd_acc_g, velocity_on, sd_acc_m_s2,
                    sd_vel_m_s, turn_on, turn_sum, out, diag, rest, rest_params):
    """One step per row (a NaN accel row: none this step), after the rest detector's step
    (``common/fast_ahrs.rest_update``; its state ``rest`` updated in place): the step gets
    the gyro less the bias learned at rest. ``state`` in and out: q (4), variance, gain,
    velocity (3), accel mean (3), last accel (3), var_vel, var_acc, velocity target (3).
    ``diag`` per row: accel_used, gain, variance, velocity (3), at_rest, the gyro bias
    learned at rest (3, rad/s). Returns the turn-rate sum (of the rate as measured)."""
    w, x, y, z = state[0], state[1], state[2], state[3]
    var, gain = state[4], state[5]
    v0, v1, v2 = state[6], state[7], state[8]
    m0, m1, m2 = state[9], state[10], state[11]
    l0, l1, l2 = state[12], state[13], state[14]
    var_vel, var_acc = state[15], state[16]
    tg0, tg1, tg2 = state[17], state[18], state[19]
    k = -1.0 / _G
    var_a = sd_acc_m_s2 * sd_acc_m_s2
    var_comb = var_a * sd_vel_m_s * sd_vel_m_s
    keep = diag.shape[0] == gyro.shape[0]  # else one scratch row (no diagnostics asked)
    r = (rest[0], rest[1], rest[2], rest[3], rest[4], rest[5], rest[6], rest[7], rest[8],
         rest[9], rest[10], rest[11])
    p = (rest_params[0], rest_params[1], rest_params[2], rest_params[3], rest_params[4],
         rest_params[5], rest_params[6], rest_params[7])
    for i in range(gyro.shape[0]):
        di = i if keep else 0
        gx, gy, gz = gyro[i, 0], gyro[i, 1], gyro[i, 2]
        dt = dts[i]
        if turn_on:
            turn_sum += math.sqrt(gx ** 2 + gy ** 2 + gz ** 2)
        used = not math.isnan(accel[i, 0])
        ax = ay = az = 0.0
        if used:
            ax, ay, az = accel[i, 0] * k, accel[i, 1] * k, accel[i, 2] * k
        r, at_rest = rest_update_kernel(r, p, gx, gy, gz, used, ax, ay, az, dt)
        (w, x, y, z, var, gain, v0, v1, v2, m0, m1, m2, l0, l1, l2, var_vel,
         var_acc) = imufilter_step_kernel(
            w, x, y, z, var, gain, gx - r[9], gy - r[10], gz - r[11], used, ax, ay, az, dt,
            alpha, sd_acc_g, velocity_on, var_a, var_comb, v0, v1, v2, m0, m1, m2, l0, l1, l2,
            var_vel, var_acc, tg0, tg1, tg2, at_rest)
        out[i, 0], out[i, 1], out[i, 2], out[i, 3] = w, x, y, z
        diag[di, 0] = 1.0 if used else 0.0
        diag[di, 1], diag[di, 2] = gain, var
        diag[di, 3], diag[di, 4], diag[di, 5] = v0, v1, v2
        diag[di, 6] = 1.0 if at_rest else 0.0
        diag[di, 7], diag[di, 8], diag[di, 9] = r[9], r[10], r[11]
    for j in range(12):
        rest[j] = r[j]
    state[0], state[1], state[2], state[3] = w, x, y, z
    state[4], state[5] = var, gain
    state[6], state[7], state[8] = v0, v1, v2
    state[9], state[10], state[11] = m0, m1, m2
    state[12], state[13], state[14] = l0, l1, l2
    state[15], state[16] = var_vel, var_acc
    return turn_sum


imufilter_rows = jit(
    _imufilter_rows, returns="f8", state="f8[::1]", gyro="f8[:, ::1]", accel="f8[:, ::1]",
    dts="f8[::1]", alpha="f8", sd_acc_g="f8", velocity_on="b1", sd_acc_m_s2="f8",
    sd_vel_m_s="f8", turn_on="b1", turn_sum="f8", out="f8[:, ::1]", diag="f8[:, ::1]",
    rest="f8[::1]", rest_params="f8[::1]")
"""The compiled kernel (see common/fast.py: the extension, or numba on the first call)."""


def pack_state(q, var, gain, vel, target) -> np.ndarray:
    """The kernel's ``state`` array from the estimator's fields."""
    return np.array([*q, var, gain, *vel.velocity, *vel.accel_mean, *vel.accel_last,
                     vel.var_vel, vel.var_acc, *target], dtype=float)


def _imufilter_sample(w, x, y, z, var, gain, gx, gy, gz, have_a, ax, ay, az, dt, alpha,
                      sd_acc_g, velocity_on, var_a, var_comb, v0, v1, v2, m0, m1, m2, l0, l1,
                      l2, var_vel, var_acc, tg0, tg1, tg2, at_rest, fx, fy, fz):
    """The step called from Python once per sample (``process()``; see ``madgwick_sample``:
    ``g`` less the bias learned at rest, ``at_rest`` the caller's rest detector's verdict),
    with the gravity-compensated acceleration in NED last."""
    (w, x, y, z, var, gain, v0, v1, v2, m0, m1, m2, l0, l1, l2, var_vel,
     var_acc) = imufilter_step_kernel(w, x, y, z, var, gain, gx, gy, gz, have_a, ax, ay, az, dt,
                                      alpha, sd_acc_g, velocity_on, var_a, var_comb, v0, v1, v2,
                                      m0, m1, m2, l0, l1, l2, var_vel, var_acc, tg0, tg1, tg2,
                                      at_rest)
    lx, ly, lz = linear_accel_ned(w, x, y, z, fx, fy, fz)
    return (w, x, y, z, var, gain, v0, v1, v2, m0, m1, m2, l0, l1, l2, var_vel, var_acc, lx, ly,
            lz)


imufilter_sample = per_sample_kernel(jit(
    _imufilter_sample, returns="UniTuple(f8, 20)", w="f8", x="f8", y="f8", z="f8", var="f8",
    gain="f8", gx="f8", gy="f8", gz="f8", have_a="b1", ax="f8", ay="f8", az="f8", dt="f8",
    alpha="f8", sd_acc_g="f8", velocity_on="b1", var_a="f8", var_comb="f8", v0="f8", v1="f8",
    v2="f8", m0="f8", m1="f8", m2="f8", l0="f8", l1="f8", l2="f8", var_vel="f8",
    var_acc="f8", tg0="f8", tg1="f8", tg2="f8", at_rest="b1", fx="f8", fy="f8", fz="f8"))
"""The per-sample kernel (used per sample only on the AOT extension: ``Kernel.per_sample``)."""
