"""The Freescale Kalman steps of ``run_6dof``/``run_9dof`` as one compiled kernel (``fast``).

Window by window and in the same order of operations as ``FreescaleKalman.step`` once the
filter is initialised and locked: the rest detector's ticks, the a priori orientation from
the window's gyro samples, the measurement matrix, the gain (build 422's partial or the full
innovation inverse, the soft gate's and the innovation gate's noise factors, none at rest),
the magnetometer rule and gate (with its reacquire turn), the corrections (with the rest
window's offset update), magnetic jamming, the inclination tracking and the next process
covariance.
The matrix products are written out as loops (numba's ``@`` needs scipy's BLAS) and the
inverse is a Gauss-Jordan with partial pivoting (identity for a singular matrix, as the
reference); they differ from numpy's BLAS/LAPACK results in the last bits only (the tests
compare with the Python step to 1e-12). Each of those blocks is a helper kernel of its own,
inlined into ``freescale_rows`` (``common.fast.inline_kernel``): split for reading, compiled
as the one function it was (tests/benchmarks/bench_freescale_split.py compares the two).

``KERNEL_SETTINGS`` lists the settings the kernel knows: ``batch.py`` uses it only for a
settings class with no other field, so a behaviour added to the filter later (with its own
setting) runs in Python until the kernel learns it, never wrongly compiled.
"""

from __future__ import annotations

import math

import numpy as np

from imuhal_filters.common.fast import inline_kernel, jit
from imuhal_filters.common.fast_ahrs import rest_update_kernel, soft_gate_distrust_kernel

KERNEL_SETTINGS = frozenset({
    "preset", "gyro_full_scale_rad_s", "accel_full_scale_m_s2", "turn_compensation",
    "nominal_airspeed_m_s", "speed_max_age_s", "wind_window_s", "airspeed_rate_tau_s",
    "velocity_rate_window_s", "sensor_rate_hz", "oversample_ratio", "coordinate_system",
    "accel_mag_input", "initialise_on_first_step", "accel_soft_gate_g", "qv_accel_g2",
    "qv_gyro_dps2", "qw_gyro_offset_dps2", "qw_accel_g2", "qw_init_theta_deg2",
    "qw_init_offset_dps2", "qw_init_theta_offset", "qw_init_accel_g2", "accel_decay",
    "qv_mag_ut2", "qw_mag_disturbance_ut2", "qw_init_disturbance_ut2", "disturbance_decay",
    "max_inclination_deg", "lock_sets_inclination", "field_strength_ut",
    "full_innovation_inverse", "accel_innovation_gate_sigma", "accel_gate_reacquire_s",
    "mag_max_accel_distrust", "mag_innovation_gate_sigma", "mag_gate_reacquire_s",
    # the estimator's handling of counted losses (it adds ticks before the kernel's steps;
    # arrays of ticks have no losses)
    "max_gap_s",
})

_DEG = math.pi / 180.0


def _quat_rotvec(q0, q1, q2, q3, rx, ry, rz):
    """quat_mul(q, quat_from_rotvec_deg(r)) of coords.py."""
    eta = math.sqrt(rx * rx + ry * ry + rz * rz) * _DEG
    if eta == 0.0:
        w, x, y, z = 1.0, 0.0, 0.0, 0.0
    else:
        f = math.sin(0.5 * eta) / eta
        w, x, y, z = math.cos(0.5 * eta), rx * _DEG * f, ry * _DEG * f, rz * _DEG * f
    return (q0 * w - q1 * x - q2 * y - q3 * z, q0 * x + q1 * w + q2 * z - q3 * y,
            q0 * y - q1 * z + q2 * w + q3 * x, q0 * z + q1 * y - q2 * x + q3 * w)


quat_rotvec = jit(_quat_rotvec)


def _matrix(q, r):
    """coords.matrix_from_quat: R (global -> sensor) = quat_to_matrix(q).T, into ``r``."""
    w, x, y, z = q[0], q[1], q[2], q[3]
    r[0, 0] = w * w + x * x - y * y - z * z
    r[1, 0] = 2 * (x * y - w * z)
    r[2, 0] = 2 * (x * z + w * y)
    r[0, 1] = 2 * (x * y + w * z)
    r[1, 1] = w * w - x * x + y * y - z * z
    r[2, 1] = 2 * (y * z - w * x)
    r[0, 2] = 2 * (x * z - w * y)
    r[1, 2] = 2 * (y * z + w * x)
    r[2, 2] = w * w - x * x - y * y + z * z


matrix = jit(_matrix)


def _matmul(a, b, out):
    """out = a @ b, terms summed in index order."""
    for i in range(a.shape[0]):
        for j in range(b.shape[1]):
            s = 0.0
            for k in range(a.shape[1]):
                s += a[i, k] * b[k, j]
            out[i, j] = s


matmul = jit(_matmul)


def _inverse_or_identity(m, out):
    """Inverse of the square ``m`` into ``out``; identity when singular."""
    n = m.shape[0]
    a = m.copy()
    for i in range(n):
        for j in range(n):
            out[i, j] = 1.0 if i == j else 0.0
    for col in range(n):
        piv = col
        for r in range(col + 1, n):
            if abs(a[r, col]) > abs(a[piv, col]):
                piv = r
        if a[piv, col] == 0.0:
            for i in range(n):
                for j in range(n):
                    out[i, j] = 1.0 if i == j else 0.0
            return
        if piv != col:
            for j in range(n):
                a[col, j], a[piv, j] = a[piv, j], a[col, j]
                out[col, j], out[piv, j] = out[piv, j], out[col, j]
        d = a[col, col]
        for j in range(n):
            a[col, j] /= d
            out[col, j] /= d
        for r in range(n):
            if r != col:
                f = a[r, col]
                if f != 0.0:
                    for j in range(n):
                        a[r, j] -= f * a[col, j]
                        out[r, j] -= f * out[col, j]


inverse_or_identity = jit(_inverse_or_identity)


def _mahalanobis3(innov, noise, factor, err, k):
    """m^2 = e^T S^-1 e for the 3 x 3 block of S = ``innov`` + diag(``noise`` * ``factor``)
    starting at row and column ``k`` and the matching rows of ``err``, by cofactors; NaN when
    the block is singular (no gate then)."""
    s00, s01, s02 = innov[k, k] + noise[k] * factor, innov[k, k + 1], innov[k, k + 2]
    s10, s11, s12 = innov[k + 1, k], innov[k + 1, k + 1] + noise[k + 1] * factor, \
        innov[k + 1, k + 2]
    s20, s21, s22 = innov[k + 2, k], innov[k + 2, k + 1], \
        innov[k + 2, k + 2] + noise[k + 2] * factor
    c00, c01, c02 = s11 * s22 - s12 * s21, s02 * s21 - s01 * s22, s01 * s12 - s02 * s11
    c10, c11, c12 = s12 * s20 - s10 * s22, s00 * s22 - s02 * s20, s02 * s10 - s00 * s12
    c20, c21, c22 = s10 * s21 - s11 * s20, s01 * s20 - s00 * s21, s00 * s11 - s01 * s10
    det = s00 * c00 + s01 * c10 + s02 * c20
    if det == 0.0:
        return math.nan
    e0, e1, e2 = err[k], err[k + 1], err[k + 2]
    return (e0 * (c00 * e0 + c01 * e1 + c02 * e2) + e1 * (c10 * e0 + c11 * e1 + c12 * e2)
            + e2 * (c20 * e0 + c21 * e1 + c22 * e2)) / det


mahalanobis3 = jit(_mahalanobis3)


def _wrap_360(a):
    a = a + 360.0 if a < 0.0 else a
    return 0.0 if a >= 360.0 else a


wrap_360 = jit(_wrap_360)


def _euler_deg(style, r):
    """The system's own (phi, theta, psi) of R (global -> sensor): the freescale_ned (0),
    _android (1) and _win8 (2) styles of imuhal.core.conventions, gimbal branches included."""
    if style == 0:
        theta = math.degrees(math.asin(max(-1.0, min(1.0, -r[0, 2]))))
        phi = math.degrees(math.atan2(r[1, 2], r[2, 2]))
        phi = -180.0 if phi == 180.0 else phi
        if theta == 90.0:
            psi = math.degrees(math.atan2(r[2, 1], r[1, 1])) + phi
        elif theta == -90.0:
            psi = math.degrees(math.atan2(-r[2, 1], r[1, 1])) - phi
        else:
            psi = math.degrees(math.atan2(r[0, 1], r[0, 0]))
        return phi, theta, wrap_360(psi)
    if style == 1:
        phi = math.degrees(math.asin(max(-1.0, min(1.0, r[0, 2]))))
        theta = math.degrees(math.atan2(-r[1, 2], r[2, 2]))
        theta = -180.0 if theta == 180.0 else theta
        if phi == 90.0:
            psi = math.degrees(math.atan2(r[1, 0], r[1, 1])) - theta
        elif phi == -90.0:
            psi = math.degrees(math.atan2(r[1, 0], r[1, 1])) + theta
        else:
            psi = math.degrees(math.atan2(-r[0, 1], r[0, 0]))
        return phi, theta, wrap_360(psi)
    if r[2, 2] == 0.0:
        phi = -90.0 if r[0, 2] >= 0.0 else 90.0
    else:
        phi = math.degrees(math.atan(-r[0, 2] / r[2, 2]))
    theta = math.degrees(math.asin(max(-1.0, min(1.0, r[1, 2]))))
    if r[2, 2] < 0.0:
        theta = 180.0 - theta
    if theta >= 180.0:
        theta -= 360.0
    if theta == 90.0:
        psi = math.degrees(math.atan2(r[0, 1], r[0, 0])) - phi
    elif theta == -90.0:
        psi = math.degrees(math.atan2(r[0, 1], r[0, 0])) + phi
    else:
        psi = math.degrees(math.atan2(-r[1, 0], r[1, 1]))
        if abs(theta) >= 90.0:
            psi += 180.0
    return phi, theta, wrap_360(psi)


euler_deg = jit(_euler_deg)


def _predict(q, b, gyro_window, fast_dt, qm, r_mi):
    """The a priori orientation ``qm`` from the window's fast gyro samples (deg/s, minus
    the bias ``b``) turning ``q``, and its matrix ``r_mi`` (global -> sensor)."""
    qm[0], qm[1], qm[2], qm[3] = q[0], q[1], q[2], q[3]
    for s in range(gyro_window.shape[0]):
        qm[0], qm[1], qm[2], qm[3] = quat_rotvec(
            qm[0], qm[1], qm[2], qm[3], (gyro_window[s, 0] - b[0]) * fast_dt,
            (gyro_window[s, 1] - b[1]) * fast_dt, (gyro_window[s, 2] - b[2]) * fast_dt)
    matrix(qm, r_mi)


predict = inline_kernel(jit(_predict))


def _measurement_matrix(c, g0, g1, g2, m0, m1, m2, use_mag, kalman_dt):
    """The measurement matrix ``c`` for the a priori gravity ``g`` and (``use_mag``)
    geomagnetic ``m`` vectors in the sensor frame."""
    for i in range(c.shape[0]):
        for j in range(c.shape[1]):
            c[i, j] = 0.0
    for blk in range(2 if use_mag else 1):
        v0, v1, v2 = (g0, g1, g2) if blk == 0 else (m0, m1, m2)
        o = 3 * blk
        sk = ((0.0, -v2, v1), (v2, 0.0, -v0), (-v1, v0, 0.0))
        for i in range(3):
            for j in range(3):
                c[o + i, j] = -_DEG * sk[i][j]
                c[o + i, 3 + j] = kalman_dt * _DEG * sk[i][j]
            c[o + i, (6 if blk == 0 else 9) + i] = 1.0 if blk == 0 else -1.0


measurement_matrix = inline_kernel(jit(_measurement_matrix))


def _measure(r_mi, accel_row, mag_row, a_sensor, m_global, use_mag, ned, gravity_positive,
             accel_decay, kalman_dt, c, err):
    """The innovations ``err`` (gravity, then geomagnetic with ``use_mag``) and the
    measurement matrix ``c`` at the a priori orientation ``r_mi``. Returns the a priori
    linear acceleration (g, the decayed ``a_sensor``)."""
    sg = 1.0 if ned else -1.0
    ax, ay, az = accel_row[0], accel_row[1], accel_row[2]
    sa = 1.0 if gravity_positive else -1.0
    gg0, gg1, gg2 = sg * r_mi[0, 2], sg * r_mi[1, 2], sg * r_mi[2, 2]
    am0, am1, am2 = accel_decay * a_sensor[0], accel_decay * a_sensor[1], \
        accel_decay * a_sensor[2]
    err[0] = sa * ax + am0 - gg0
    err[1] = sa * ay + am1 - gg1
    err[2] = sa * az + am2 - gg2
    mg0 = r_mi[0, 0] * m_global[0] + r_mi[0, 1] * m_global[1] + r_mi[0, 2] * m_global[2]
    mg1 = r_mi[1, 0] * m_global[0] + r_mi[1, 1] * m_global[1] + r_mi[1, 2] * m_global[2]
    mg2 = r_mi[2, 0] * m_global[0] + r_mi[2, 1] * m_global[1] + r_mi[2, 2] * m_global[2]
    measurement_matrix(c, gg0, gg1, gg2, mg0, mg1, mg2, use_mag, kalman_dt)
    if use_mag:
        err[3] = mag_row[0] - mg0
        err[4] = mag_row[1] - mg1
        err[5] = mag_row[2] - mg2
    return am0, am1, am2


measure = inline_kernel(jit(_measure))


def _accel_gate_factor(innov, noise, err, factor, gate_sigma, gate_reacquire_s,
                       gate_closed, kalman_dt):
    """The soft gate's noise ``factor`` times the innovation gate's: the gravity
    innovation's Mahalanobis distance against S (kalman.py's _innovation_noise_factor),
    none if S is singular or without a gate (``gate_sigma`` 0). Updates how long the gate
    has been closed (``gate_closed[0]``, s)."""
    if gate_sigma > 0.0:
        m2 = mahalanobis3(innov, noise, factor, err, 0)
        if not math.isnan(m2):
            ratio2 = m2 / (gate_sigma * gate_sigma)
            if ratio2 <= 1.0:
                gate_closed[0] = 0.0
            else:
                gate_closed[0] += kalman_dt
                if gate_closed[0] <= gate_reacquire_s:
                    factor *= ratio2 * ratio2
    return factor


accel_gate_factor = inline_kernel(jit(_accel_gate_factor))


def _at_length(mag_row, p0, p1, p2, length, out):
    """``mag_row`` minus the predicted field ``p`` scaled to ``length`` into ``out[3:6]``
    (kalman.py's _innovation_at_length)."""
    n = math.sqrt(p0 * p0 + p1 * p1 + p2 * p2)
    f = 1.0 if n == 0.0 else length / n
    out[3], out[4], out[5] = mag_row[0] - f * p0, mag_row[1] - f * p1, mag_row[2] - f * p2


at_length = inline_kernel(jit(_at_length))


def _mag_gate_verdict(innov, noise, mag_row, r_mi, m_global, state, gate_sigma, reacquire_s,
                      length_step, kalman_dt, scratch):
    """The magnetometer innovation gate and its reacquire rule (kalman.py's
    _mag_gate_verdict, state ``state`` as its ``mag_gate``; ``reacquire_s`` inf: never):
    the heading correction (deg) to apply before the magnetometer steers, 0 to steer as it
    is, NaN to leave the orientation to the gyro."""
    mg0 = r_mi[0, 0] * m_global[0] + r_mi[0, 1] * m_global[1] + r_mi[0, 2] * m_global[2]
    mg1 = r_mi[1, 0] * m_global[0] + r_mi[1, 1] * m_global[1] + r_mi[1, 2] * m_global[2]
    mg2 = r_mi[2, 0] * m_global[0] + r_mi[2, 1] * m_global[1] + r_mi[2, 2] * m_global[2]
    length = state[3]
    x, y, z = mag_row[0], mag_row[1], mag_row[2]
    diff = math.sqrt(x * x + y * y + z * z) - length
    if diff > 0.0:
        state[3] += length_step
    elif diff < 0.0:
        state[3] += -length_step
    gate2 = gate_sigma * gate_sigma
    at_length(mag_row, mg0, mg1, mg2, length, scratch)
    m2 = mahalanobis3(innov, noise, 1.0, scratch, 3)
    if math.isnan(m2) or m2 <= gate2:
        state[0], state[1], state[2] = 0.0, 0.0, 0.0
        return 0.0
    if math.isinf(reacquire_s):
        return math.nan
    # the measured field in the global frame (r_mi.T @ mag) against the reference
    g0 = r_mi[0, 0] * x + r_mi[1, 0] * y + r_mi[2, 0] * z
    g1 = r_mi[0, 1] * x + r_mi[1, 1] * y + r_mi[2, 1] * z
    psi = math.atan2(m_global[0] * g1 - m_global[1] * g0,
                     m_global[0] * g0 + m_global[1] * g1)
    state[1] += math.cos(psi)
    state[2] += math.sin(psi)
    mean = math.atan2(state[2], state[1])
    co, si = math.cos(mean), math.sin(mean)
    t0 = co * m_global[0] + -si * m_global[1] + 0.0 * m_global[2]
    t1 = si * m_global[0] + co * m_global[1] + 0.0 * m_global[2]
    t2 = 0.0 * m_global[0] + 0.0 * m_global[1] + 1.0 * m_global[2]
    at_length(mag_row, r_mi[0, 0] * t0 + r_mi[0, 1] * t1 + r_mi[0, 2] * t2,
              r_mi[1, 0] * t0 + r_mi[1, 1] * t1 + r_mi[1, 2] * t2,
              r_mi[2, 0] * t0 + r_mi[2, 1] * t1 + r_mi[2, 2] * t2, length, scratch)
    m2_turned = mahalanobis3(innov, noise, 1.0, scratch, 3)
    if math.isnan(m2_turned) or m2_turned > gate2:
        state[0], state[1], state[2] = 0.0, 0.0, 0.0
        return math.nan
    state[0] += kalman_dt
    if state[0] < reacquire_s:
        return math.nan
    state[0], state[1], state[2] = 0.0, 0.0, 0.0
    return math.degrees(mean)


mag_gate_verdict = inline_kernel(jit(_mag_gate_verdict))


def _turn_about_vertical(qm, angle_deg):
    """``qm`` turned on its global side by ``angle_deg`` about the global z axis (kalman.py's
    quat_mul(quat_about_vertical_deg(angle_deg), q))."""
    half = math.radians(angle_deg) / 2.0
    pw, px, py, pz = math.cos(half), 0.0, 0.0, math.sin(half)
    qw, qx, qy, qz = qm[0], qm[1], qm[2], qm[3]
    qm[0] = pw * qw - px * qx - py * qy - pz * qz
    qm[1] = pw * qx + px * qw + py * qz - pz * qy
    qm[2] = pw * qy - px * qz + py * qw + pz * qx
    qm[3] = pw * qz + px * qy - py * qx + pz * qw


turn_about_vertical = inline_kernel(jit(_turn_about_vertical))


def _invert_innovation(innov, noise, factor, use_mag, full_inverse, inv):
    """S = C Qw C^T + the measurement noise (the accelerometer's times ``factor``), filled
    from its top half as the reference does, and its inverse into ``inv``: build 422's
    partial inverse (only the gravity block inverted) unless ``full_inverse``."""
    nm = innov.shape[0]
    for i in range(nm):
        innov[i, i] += noise[i] * factor if i < 3 else noise[i]
    for i in range(nm):
        for j in range(i):
            innov[i, j] = innov[j, i]
    if use_mag and not full_inverse:
        for i in range(nm):
            for j in range(nm):
                inv[i, j] = innov[i, j]
        g3 = np.empty((3, 3))
        inverse_or_identity(innov[:3, :3].copy(), g3)
        for i in range(3):
            for j in range(3):
                inv[i, j] = g3[i, j]
    else:
        inverse_or_identity(innov, inv)


invert_innovation = inline_kernel(jit(_invert_innovation))


def _error_vector(k, err, xe, use_mag, mag_steers, field):
    """The a posteriori error vector ``xe`` = K err: the geomagnetic innovation's share
    only when the magnetometer steers and is not jammed (the disturbance estimate above
    twice the ``field``). Returns whether it is jammed."""
    for i in range(xe.shape[0]):
        xe[i] = k[i, 0] * err[0] + k[i, 1] * err[1] + k[i, 2] * err[2]
    if not use_mag:
        return False
    for i in range(9, 12):
        xe[i] += k[i, 3] * err[3] + k[i, 4] * err[4] + k[i, 5] * err[5]
    jamming = xe[9] * xe[9] + xe[10] * xe[10] + xe[11] * xe[11] > 4.0 * field * field
    if not jamming and mag_steers:
        for i in range(9):
            xe[i] += k[i, 3] * err[3] + k[i, 4] * err[4] + k[i, 5] * err[5]
    return jamming


error_vector = inline_kernel(jit(_error_vector))


def _correct(qm, xe, q, b, a_sensor, am0, am1, am2):
    """The corrections: the a posteriori orientation (``q``, unit, scalar part >= 0;
    identity if the correction degenerates), gyro bias ``b`` and linear acceleration
    ``a_sensor`` from the a priori ones and the error vector ``xe``."""
    p0, p1, p2, p3 = quat_rotvec(qm[0], qm[1], qm[2], qm[3], -xe[0], -xe[1], -xe[2])
    nq = math.sqrt(p0 * p0 + p1 * p1 + p2 * p2 + p3 * p3)
    if not nq > 1e-3:
        p0, p1, p2, p3 = 1.0, 0.0, 0.0, 0.0
    else:
        p0, p1, p2, p3 = p0 / nq, p1 / nq, p2 / nq, p3 / nq
        if p0 < 0.0:
            p0, p1, p2, p3 = -p0, -p1, -p2, -p3
    q[0], q[1], q[2], q[3] = p0, p1, p2, p3
    for i in range(3):
        b[i] = b[i] - xe[3 + i]
    a_sensor[0], a_sensor[1], a_sensor[2] = am0 - xe[6], am1 - xe[7], am2 - xe[8]


correct = inline_kernel(jit(_correct))


def _track_inclination(q, xe, r_mi, m_global, incl, ned, field, max_incl_deg):
    """The geomagnetic vector ``m_global`` and inclination ``incl[0]`` (deg, within
    +-``max_incl_deg``) corrected by the disturbance estimate ``xe[9:12]`` (sensor frame)
    at the a posteriori orientation ``q``; ``r_mi`` is scratch."""
    matrix(q, r_mi)
    # d in the global frame: r_pl.T @ xe[D]
    d0 = r_mi[0, 0] * xe[9] + r_mi[1, 0] * xe[10] + r_mi[2, 0] * xe[11]
    d1 = r_mi[0, 1] * xe[9] + r_mi[1, 1] * xe[10] + r_mi[2, 1] * xe[11]
    d2 = r_mi[0, 2] * xe[9] + r_mi[1, 2] * xe[10] + r_mi[2, 2] * xe[11]
    north = 0 if ned else 1
    sign_down = 1.0 if ned else -1.0
    down = sign_down * (m_global[2] - d2)
    horiz = max(m_global[north] - (d0 if north == 0 else d1), 0.0)
    hyp = math.hypot(down, horiz)
    if hyp == 0.0:
        return
    sin_d, cos_d = down / hyp, horiz / hyp
    lim = math.radians(max_incl_deg)
    if abs(sin_d) > math.sin(lim):
        sin_d, cos_d = math.copysign(math.sin(lim), sin_d), math.cos(lim)
    incl[0] = math.degrees(math.asin(max(-1.0, min(1.0, sin_d))))
    m_global[north] = field * cos_d
    m_global[2] = sign_down * field * sin_d


track_inclination = inline_kernel(jit(_track_inclination))


def _posterior(c, qw, k, cq, p):
    """P+ = Qw - K C Qw into ``p``, its upper triangle mirrored as the reference does
    (kalman.py's _posterior); ``cq`` is scratch."""
    matmul(c, qw, cq)
    matmul(k, cq, p)
    n = qw.shape[0]
    for i in range(n):
        for j in range(i, n):
            p[i, j] = qw[i, j] - p[i, j]
    for i in range(n):
        for j in range(i):
            p[i, j] = p[j, i]


posterior = inline_kernel(jit(_posterior))


def _fuse_rest_offset(xe, p, b, gyro_window, qv_gyro, s_bb, s_inv, gain, pb):
    """At rest the window's mean gyro reading measures the offset alone: a second,
    sequential Kalman update of the error vector ``xe`` and its covariance ``p`` (P+, in
    place) with the offset block as the measurement (kalman.py's _fuse_rest_offset);
    ``s_bb`` and ``s_inv`` (3 x 3), ``gain`` (n x 3) and ``pb`` (3 x n) are scratch."""
    n = p.shape[0]
    ratio = gyro_window.shape[0]
    t0 = t1 = t2 = 0.0
    for r in range(ratio):
        t0, t1, t2 = t0 + gyro_window[r, 0], t1 + gyro_window[r, 1], t2 + gyro_window[r, 2]
    e0 = b[0] - xe[3] - t0 / ratio
    e1 = b[1] - xe[4] - t1 / ratio
    e2 = b[2] - xe[5] - t2 / ratio
    for i in range(3):
        for j in range(3):
            s_bb[i, j] = p[3 + i, 3 + j] + (qv_gyro if i == j else 0.0)
    inverse_or_identity(s_bb, s_inv)
    for i in range(n):
        for j in range(3):
            acc = 0.0
            for m in range(3):
                acc += p[i, 3 + m] * s_inv[m, j]
            gain[i, j] = acc
    for i in range(n):
        xe[i] += gain[i, 0] * e0 + gain[i, 1] * e1 + gain[i, 2] * e2
    for i in range(3):
        for j in range(n):
            pb[i, j] = p[3 + i, j]
    for i in range(n):
        for j in range(i, n):
            p[i, j] -= gain[i, 0] * pb[0, j] + gain[i, 1] * pb[1, j] + gain[i, 2] * pb[2, j]
    for i in range(n):
        for j in range(i):
            p[i, j] = p[j, i]


fuse_rest_offset = inline_kernel(jit(_fuse_rest_offset))


def _next_covariance(p, qw, use_mag, kalman_dt, accel_decay, qw_gyro_offset, qv_gyro,
                     qw_accel, dist_decay, qw_dist):
    """The next process covariance ``qw`` from the a posteriori covariance ``p``'s diagonal
    (diagonal, with the orientation-offset coupling terms; kalman.py's
    _next_covariance)."""
    n = qw.shape[0]
    for i in range(n):
        for j in range(n):
            qw[i, j] = 0.0
    for i in range(3):
        poo, ptt, paa = p[3 + i, 3 + i], p[i, i], p[6 + i, 6 + i]
        qw[3 + i, 3 + i] = poo + qw_gyro_offset
        qw[i, i] = ptt + kalman_dt * kalman_dt * (poo + qw_gyro_offset + qv_gyro)
        qw[6 + i, 6 + i] = accel_decay ** 2 * paa + qw_accel
        if use_mag:
            qw[9 + i, 9 + i] = dist_decay ** 2 * p[9 + i, 9 + i] + qw_dist
    for i in range(3):
        qw[i, 3 + i] = qw[3 + i, i] = -kalman_dt * qw[3 + i, 3 + i]


next_covariance = inline_kernel(jit(_next_covariance))


def _window_at_rest(rest, rest_params, gyro_rad, accel_fast, fast_dt):
    """The rest detector (``common/fast_ahrs.rest_update``; its state ``rest`` updated in
    place) stepped once per fast tick of the window with the tick's gyro (rad/s) and
    accelerometer rows (rest.py's WindowRest): whether it found the board at rest at every
    tick."""
    if rest_params[0] != 1.0:
        return False
    r = (rest[0], rest[1], rest[2], rest[3], rest[4], rest[5], rest[6], rest[7], rest[8],
         rest[9], rest[10], rest[11])
    p = (rest_params[0], rest_params[1], rest_params[2], rest_params[3], rest_params[4],
         rest_params[5], rest_params[6], rest_params[7])
    window = True
    for t in range(gyro_rad.shape[0]):
        r, at_rest = rest_update_kernel(r, p, gyro_rad[t, 0], gyro_rad[t, 1], gyro_rad[t, 2],
                                        True, accel_fast[t, 0], accel_fast[t, 1],
                                        accel_fast[t, 2], fast_dt)
        window = window and at_rest
    for j in range(12):
        rest[j] = r[j]
    return window


window_at_rest = inline_kernel(jit(_window_at_rest))


def _freescale_rows(q, b, a_sensor, m_global, qw, incl, accel, gyro, mag, use_mag, ned,
                    gravity_positive, fast_dt, kalman_dt, accel_decay, soft_width, noise,
                    full_inverse, field, qw_gyro_offset, qv_gyro, qw_accel, dist_decay,
                    qw_dist, max_incl_deg, style, gate_sigma, gate_reacquire_s,
                    gate_closed, mag_max_distrust, mag_gate_sigma, mag_gate, mag_reacquire_s,
                    length_step, rest, rest_params, gyro_rad, accel_fast, out_q, out_b,
                    out_incl, out_jam, out_euler, out_rest):
    """One Kalman step per window ``k``: ``accel[k]``, ``mag[k]`` the measurements, ``gyro[k]``
    (ratio x 3) the fast samples. The state arrays (q, b, a_sensor, m_global, qw, incl[0])
    are updated in place; per step the a posteriori q, b, inclination, jamming flag and the
    system's Euler angles (``style``: 0 ned, 1 android, 2 win8). ``gate_sigma`` (0: none),
    ``gate_reacquire_s`` and the state ``gate_closed[0]`` (s) are the innovation gate's,
    ``mag_max_distrust`` (0: none) the magnetometer rule's; ``mag_gate_sigma`` (0: none),
    ``mag_reacquire_s`` (inf: never), the state ``mag_gate`` (4) and ``length_step`` (how far
    the field length moves per step, uT) the magnetometer innovation gate's
    (kalman.py). ``rest`` (12, in place) and ``rest_params`` (8) are the rest detector's
    state and parameters, ticked with each window's fast gyro (``gyro_rad``, rad/s) and
    accelerometer (``accel_fast``) rows; a window at rest at every tick is fused as a rest
    (``out_rest``)."""
    n = qw.shape[0]
    nm = 6 if use_mag else 3
    r_mi = np.empty((3, 3))
    c = np.zeros((nm, n))
    ct = np.empty((n, nm))
    qw_ct = np.empty((n, nm))
    innov = np.empty((nm, nm))
    inv = np.empty((nm, nm))
    k = np.empty((n, nm))
    cq = np.empty((nm, n))
    kcq = np.empty((n, n))
    xe = np.empty(n)
    err = np.empty(nm)
    qm = np.empty(4)
    scratch = np.empty(6)
    s_bb, s_inv = np.empty((3, 3)), np.empty((3, 3))
    gain, pb = np.empty((n, 3)), np.empty((3, n))
    for step in range(accel.shape[0]):
        at_rest = window_at_rest(rest, rest_params, gyro_rad[step], accel_fast[step], fast_dt)
        predict(q, b, gyro[step], fast_dt, qm, r_mi)
        am0, am1, am2 = measure(r_mi, accel[step], mag[step], a_sensor, m_global, use_mag,
                                ned, gravity_positive, accel_decay, kalman_dt, c, err)
        # gain
        ax, ay, az = accel[step, 0], accel[step, 1], accel[step, 2]
        factor = soft_gate_distrust_kernel(math.sqrt(ax * ax + ay * ay + az * az),
                                           soft_width) ** 2
        for i in range(n):
            for j in range(nm):
                ct[i, j] = c[j, i]
        matmul(qw, ct, qw_ct)
        matmul(c, qw_ct, innov)
        if at_rest:  # the reading is gravity: nothing to gate
            factor = 1.0
            gate_closed[0] = 0.0
        else:
            factor = accel_gate_factor(innov, noise, err, factor, gate_sigma,
                                       gate_reacquire_s, gate_closed, kalman_dt)
        mag_steers = mag_max_distrust <= 0.0 or factor <= mag_max_distrust
        gated_out = False
        if use_mag and mag_steers and mag_gate_sigma > 0.0:
            yaw_deg = mag_gate_verdict(innov, noise, mag[step], r_mi, m_global, mag_gate,
                                       mag_gate_sigma, mag_reacquire_s, length_step,
                                       kalman_dt, scratch)
            mag_steers = not math.isnan(yaw_deg)
            gated_out = not mag_steers
            if mag_steers and yaw_deg != 0.0:  # reacquired: the heading turned first
                turn_about_vertical(qm, -yaw_deg)
                matrix(qm, r_mi)
                am0, am1, am2 = measure(r_mi, accel[step], mag[step], a_sensor, m_global,
                                        use_mag, ned, gravity_positive, accel_decay,
                                        kalman_dt, c, err)
                for i in range(n):
                    for j in range(nm):
                        ct[i, j] = c[j, i]
                matmul(qw, ct, qw_ct)
                matmul(c, qw_ct, innov)
        invert_innovation(innov, noise, factor, use_mag, full_inverse, inv)
        matmul(qw_ct, inv, k)
        jamming = error_vector(k, err, xe, use_mag, mag_steers, field)
        posterior(c, qw, k, cq, kcq)
        if at_rest:
            fuse_rest_offset(xe, kcq, b, gyro[step], qv_gyro, s_bb, s_inv, gain, pb)
        correct(qm, xe, q, b, a_sensor, am0, am1, am2)
        if use_mag and not jamming and not gated_out:
            track_inclination(q, xe, r_mi, m_global, incl, ned, field, max_incl_deg)
        next_covariance(kcq, qw, use_mag, kalman_dt, accel_decay, qw_gyro_offset, qv_gyro,
                        qw_accel, dist_decay, qw_dist)
        out_rest[step] = at_rest
        out_q[step, 0], out_q[step, 1], out_q[step, 2], out_q[step, 3] = q[0], q[1], q[2], q[3]
        out_b[step, 0], out_b[step, 1], out_b[step, 2] = b[0], b[1], b[2]
        out_incl[step] = incl[0]
        out_jam[step] = jamming
        matrix(q, r_mi)
        out_euler[step, 0], out_euler[step, 1], out_euler[step, 2] = euler_deg(style, r_mi)


freescale_rows = jit(
    _freescale_rows, returns="none", q="f8[::1]", b="f8[::1]", a_sensor="f8[::1]",
    m_global="f8[::1]", qw="f8[:, ::1]", incl="f8[::1]", accel="f8[:, ::1]",
    gyro="f8[:, :, ::1]", mag="f8[:, ::1]", use_mag="b1", ned="b1", gravity_positive="b1",
    fast_dt="f8", kalman_dt="f8", accel_decay="f8", soft_width="f8", noise="f8[::1]",
    full_inverse="b1", field="f8", qw_gyro_offset="f8", qv_gyro="f8", qw_accel="f8",
    dist_decay="f8", qw_dist="f8", max_incl_deg="f8", style="i8", gate_sigma="f8",
    gate_reacquire_s="f8", gate_closed="f8[::1]", mag_max_distrust="f8", mag_gate_sigma="f8",
    mag_gate="f8[::1]", mag_reacquire_s="f8", length_step="f8", rest="f8[::1]",
    rest_params="f8[::1]", gyro_rad="f8[:, :, ::1]", accel_fast="f8[:, :, ::1]",
    out_q="f8[:, ::1]", out_b="f8[:, ::1]", out_incl="f8[::1]", out_jam="b1[::1]",
    out_euler="f8[:, ::1]", out_rest="b1[::1]")
"""The compiled kernel (see common/fast.py: the extension, or numba on the first call)."""
