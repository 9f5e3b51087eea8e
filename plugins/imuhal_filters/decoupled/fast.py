"""The "decoupled" filter's step as one compiled kernel (``fast`` extra; see common/fast.py).

It repeats, step by step and in the same order of operations, what ``DecoupledKernel.step``
(core.py) does with its parts: the strapdown, the rest detector, the rotation pace
(pace.py), the manoeuvre detector (common/innovation.py) and its look-back (lookback.py),
the accelerometer filters (butterworth.py), the gyro bias Kalman filter (bias.py) and the
heading with its disturbance check. Python stays the reference: the tests compare the two
(tests/filters/test_decoupled_compiled.py).

The state lives in two float arrays the estimator keeps (``state_arrays`` fills them from a
``DecoupledKernel``, ``load_state`` writes them back): ``S`` (the ``_S_*`` layout below; a
filter or reference that is None in Python has its "set" slot 0) and ``L``, the look-back's
kept input as a ring of ``lookback.Entry`` rows (its head and count in ``S``). A step adds
at most one entry; the caller grows ``L`` before it is full.

Not covered (``covers`` says so; those settings keep the Python step): the innovation-speed
weight (``preset: adaptive``), the soft gate and the turbulence correction (``preset:
flight``).
"""

from __future__ import annotations

import math

import numpy as np

from imuhal_filters.common.fast import jit, per_sample_kernel
from imuhal_filters.common.fast_ahrs import TO_G as _TO_G
from imuhal_filters.common.fast_frames import linear_accel_ned
from imuhal_filters.common.innovation import GAP_VELOCITY_KEPT
from imuhal_filters.madgwick.fast import block_case, mag_rows_kernel, nominal_fused, step_lengths

_G = 9.80665  # STANDARD_GRAVITY_M_S2
_TWO_PI = 2.0 * math.pi

# ---------------------------------------------------------------- state layout (S)
_QG = 0          # q_gyro (4)
_QI = 4          # q_inc (4)
_DELTA = 8       # delta_rad
_ACCI = 9        # acc_i: set, 3 values
_ACCF = 13       # accelerometer filter: set, 6 values
_RF = 20         # R filter: set, 18 values
_RBF = 39        # R b filter: set, 4 values
_B = 44          # bias (3)
_BP = 47         # bias covariance (9, row by row)
_GLP = 56        # gyro low-pass: set, 3
_ALP = 60        # accelerometer low-pass: set, 3
_REST_S = 64
_MREF = 65       # magnetic reference: set, norm, dip
_MCAND = 68      # candidate: set, norm, dip
_MCAND_S = 71
_MDIST = 72
_MAN = 73        # manoeuvre detector: drift 3, mean 3, mean_sq, v 3 (10)
_LB = 83         # look-back: kept_s, last_weight, episode set, episode_s
_DV = 87         # episode velocity change (3)
_PEAK = 90       # its peak (3)
_READM = 93      # readmitted episodes
_BEFORE = 94     # the filter before the kept input: set, 6
_PACE = 101      # pace: innovation_sq, rate_sq, started
_MISSED = 104    # a step since the last accelerometer reading had none
_HEAD = 105      # look-back ring: head, count (last: S[-1] is the count)
STATE_SIZE = 107

# ---------------------------------------------------------------- parameters (P)
(P_TAU_ACC, P_TAU_REST, P_TAU_MAG, P_REST_GYRO_TH, P_REST_ACC_TH, P_REST_TAU, P_REST_MIN,
 P_BIAS_CLIP_CORE, P_SIGMA_INIT, P_FORGETTING, P_SIGMA_MOTION, P_VERT_FORGET, P_SIGMA_REST,
 P_KF_CLIP, P_MAG_NORM_TH, P_MAG_DIP_TH_RAD, P_MAG_REF_TAU, P_MAG_NEW, P_MAN_ON, P_M_SPEED,
 P_M_RATIO, P_M_WINDOW, P_M_LEAK, P_M_DRIFT_TAU, P_M_FLOOR, P_M_POWER, P_LB_S, P_LB_TOL,
 P_PACE_ON, P_PACE_EPS, P_PACE_FLOOR, P_MOTION_ON, P_REST_ON) = range(33)
PARAMS_SIZE = 33
ENTRY = 10  # a look-back entry: a (3), dt, weight, base, innovation (3), pace


# ---------------------------------------------------------------- small helpers
def _qmul(pw, px, py, pz, qw, qx, qy, qz):
    return (pw * qw - px * qx - py * qy - pz * qz,
            pw * qx + px * qw + py * qz - pz * qy,
            pw * qy - px * qz + py * qw + pz * qx,
            pw * qz + px * qy - py * qx + pz * qw)


qmul = jit(_qmul)


def _rotate(w, x, y, z, vx, vy, vz):
    """``quat.to_global``."""
    tx = 2.0 * (y * vz - z * vy)
    ty = 2.0 * (z * vx - x * vz)
    tz = 2.0 * (x * vy - y * vx)
    return (vx + w * tx + (y * tz - z * ty),
            vy + w * ty + (z * tx - x * tz),
            vz + w * tz + (x * ty - y * tx))


rotate = jit(_rotate)


def _rotvec(x, y, z):
    """``core._rotvec_quat``."""
    a = math.sqrt(x * x + y * y + z * z)
    if a < 1e-12:
        return (1.0, 0.5 * x, 0.5 * y, 0.5 * z)
    s = math.sin(0.5 * a) / a
    return (math.cos(0.5 * a), x * s, y * s, z * s)


rotvec = jit(_rotvec)


def _unit(w, x, y, z):
    n = 1.0 / math.sqrt(w * w + x * x + y * y + z * z)
    return (w * n, x * n, y * n, z * n)


unit = jit(_unit)


def _pymax(a, b):
    """Python's ``max(a, b)``: ``a`` unless ``b`` is greater."""
    return b if b > a else a


pymax = jit(_pymax)


def _pyclip(v, c):
    """``max(-c, min(c, v))`` as Python evaluates it."""
    m = v if v < c else c
    return m if m > -c else -c


pyclip = jit(_pyclip)


def _hypot(x, y):
    return math.hypot(x, y)


hypot2 = jit(_hypot)


def _wrap(a):
    return (a + math.pi) % _TWO_PI - math.pi


wrap = jit(_wrap)


def _bw_step(S, off, x, n, dt, sigma):
    """``ButterworthLowPass.step``: the filter whose "set" slot is ``S[off]`` and whose
    2 n values follow it, one input ``x`` (n values) over ``dt``."""
    if S[off] == 0.0:
        S[off] = 1.0
        for i in range(n):
            S[off + 1 + i] = x[i]
            S[off + 1 + n + i] = 0.0
    e = math.exp(-sigma * dt)
    c, si = math.cos(sigma * dt), math.sin(sigma * dt)
    a, b, cc, d = e * (c + si), e * si / sigma, -2.0 * sigma * e * si, e * (c - si)
    for i in range(n):
        z, zd = S[off + 1 + i] - x[i], S[off + 1 + n + i]
        S[off + 1 + i] = x[i] + a * z + b * zd
        S[off + 1 + n + i] = cc * z + d * zd


bw_step = jit(_bw_step)


def _inclination_correction(qw, qx, qy, qz, ex, ey, ez):
    """``core.inclination_correction``: the new q_inc and the correction (x, y; z is 0)."""
    n = math.sqrt(ex * ex + ey * ey + ez * ez)
    if n < 1e-9:
        return qw, qx, qy, qz, 0.0, 0.0
    ex, ey, ez = ex / n, ey / n, ez / n
    s = hypot2(ex, ey)
    if s < 1e-12:
        return qw, qx, qy, qz, 0.0, 0.0
    angle = math.atan2(s, ez)
    rx, ry = ey / s * angle, -ex / s * angle
    rw, rxx, ryy, rzz = rotvec(rx, ry, 0.0)
    w, x, y, z = qmul(rw, rxx, ryy, rzz, qw, qx, qy, qz)
    w, x, y, z = unit(w, x, y, z)
    return w, x, y, z, rx, ry


inclination_correction = jit(_inclination_correction)


# ---------------------------------------------------------------- the bias Kalman filter
def _mul(a, b, out):
    for i in range(3):
        for j in range(3):
            out[i, j] = a[i, 0] * b[0, j] + a[i, 1] * b[1, j] + a[i, 2] * b[2, j]


mul = jit(_mul)


def _inv3(m, out):
    a, b, c = m[0, 0], m[0, 1], m[0, 2]
    d, e, f = m[1, 0], m[1, 1], m[1, 2]
    g, h, i = m[2, 0], m[2, 1], m[2, 2]
    A, B, C = e * i - f * h, f * g - d * i, d * h - e * g
    det = a * A + b * B + c * C
    r = 1.0 / det
    out[0, 0], out[0, 1], out[0, 2] = A * r, (c * h - b * i) * r, (b * f - c * e) * r
    out[1, 0], out[1, 1], out[1, 2] = B * r, (a * i - c * g) * r, (c * d - a * f) * r
    out[2, 0], out[2, 1], out[2, 2] = C * r, (b * g - a * h) * r, (a * e - b * d) * r


inv3 = jit(_inv3)


def _kf_update(S, P, e0, e1, e2, h, w0, w1, w2):
    """``GyroBiasKalman._update`` on the bias and covariance in ``S``."""
    c = P[P_KF_CLIP]
    e0, e1, e2 = pyclip(e0, c), pyclip(e1, c), pyclip(e2, c)
    p = np.empty((3, 3))
    for i in range(3):
        for j in range(3):
            p[i, j] = S[_BP + 3 * i + j]
    ph_t = np.empty((3, 3))  # P H^T
    for i in range(3):
        for j in range(3):
            ph_t[i, j] = p[i, 0] * h[j, 0] + p[i, 1] * h[j, 1] + p[i, 2] * h[j, 2]
    s = np.empty((3, 3))
    mul(h, ph_t, s)
    s[0, 0] += w0
    s[1, 1] += w1
    s[2, 2] += w2
    s_inv = np.empty((3, 3))
    inv3(s, s_inv)
    k = np.empty((3, 3))
    mul(ph_t, s_inv, k)
    b0, b1, b2 = S[_B], S[_B + 1], S[_B + 2]
    S[_B] = pyclip(b0 + k[0, 0] * e0 + k[0, 1] * e1 + k[0, 2] * e2, c)
    S[_B + 1] = pyclip(b1 + k[1, 0] * e0 + k[1, 1] * e1 + k[1, 2] * e2, c)
    S[_B + 2] = pyclip(b2 + k[2, 0] * e0 + k[2, 1] * e1 + k[2, 2] * e2, c)
    kh = np.empty((3, 3))
    mul(k, h, kh)
    khp = np.empty((3, 3))
    mul(kh, p, khp)
    for i in range(3):
        for j in range(3):
            S[_BP + 3 * i + j] = p[i, j] - khp[i, j]


kf_update = jit(_kf_update)


def _kf_w(P, sigma, dt):
    """``GyroBiasKalman._w``."""
    p = sigma ** 2
    return p * p / pymax(0.01 * dt / P[P_FORGETTING], 1e-30) + p


kf_w = jit(_kf_w)


def _bias_step(S, P, c0, c1, dt, dt_filter, rest):
    """``DecoupledKernel._bias_step`` after a correction (c0, c1, 0)."""
    w, x, y, z = qmul(S[_QI], S[_QI + 1], S[_QI + 2], S[_QI + 3],
                      S[_QG], S[_QG + 1], S[_QG + 2], S[_QG + 3])
    r = np.empty(9)
    r[0], r[1], r[2] = 1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)
    r[3], r[4], r[5] = 2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)
    r[6], r[7], r[8] = 2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)
    b0, b1, b2 = S[_B], S[_B + 1], S[_B + 2]
    rb = np.empty(2)
    rb[0] = r[0] * b0 + r[1] * b1 + r[2] * b2
    rb[1] = r[3] * b0 + r[4] * b1 + r[5] * b2
    sigma = 1.0 / P[P_TAU_ACC]
    bw_step(S, _RF, r, 9, dt_filter, sigma)
    bw_step(S, _RBF, rb, 2, dt_filter, sigma)
    if dt <= 0.0:
        return
    # predict
    v = 0.01 * dt / P[P_FORGETTING]
    p0 = P[P_SIGMA_INIT] ** 2
    for i in range(3):
        if S[_BP + 4 * i] < p0:
            S[_BP + 4 * i] += v
    h = np.empty((3, 3))
    if rest:
        for i in range(3):
            for j in range(3):
                h[i, j] = 1.0 if i == j else 0.0
        wr = kf_w(P, P[P_SIGMA_REST], dt)
        kf_update(S, P, S[_GLP + 1] - b0, S[_GLP + 2] - b1, S[_GLP + 3] - b2, h, wr, wr, wr)
        return
    if P[P_MOTION_ON] == 0.0:
        return
    for i in range(3):
        for j in range(3):
            h[i, j] = S[_RF + 1 + 3 * i + j]
    hb0 = h[0, 0] * b0 + h[0, 1] * b1 + h[0, 2] * b2
    hb1 = h[1, 0] * b0 + h[1, 1] * b1 + h[1, 2] * b2
    hb2 = h[2, 0] * b0 + h[2, 1] * b1 + h[2, 2] * b2
    e0 = -c0 / dt + S[_RBF + 1] - hb0
    e1 = -c1 / dt + S[_RBF + 2] - hb1
    e2 = -hb2
    wm = kf_w(P, P[P_SIGMA_MOTION], dt)
    kf_update(S, P, e0, e1, e2, h, wm, wm, wm / pymax(P[P_VERT_FORGET], 1e-10))


bias_step = jit(_bias_step)


# ---------------------------------------------------------------- rest, pace, manoeuvre
def _follow3(S, at, k, x, y, z):
    """``core.follow``: the first-order low-pass held at ``S[at + 1:at + 4]`` one step of
    weight ``k`` toward (x, y, z); its first input (``S[at]`` still 0.0) starts it."""
    if S[at] == 0.0:
        S[at], S[at + 1], S[at + 2], S[at + 3] = 1.0, x, y, z
    else:
        v0, v1, v2 = S[at + 1], S[at + 2], S[at + 3]
        S[at + 1], S[at + 2], S[at + 3] = v0 + k * (x - v0), v1 + k * (y - v1), v2 + k * (z - v2)


follow3 = jit(_follow3)


def _rest_step(S, P, gx, gy, gz, have_a, ax, ay, az, dt):
    """``DecoupledKernel._rest_step``."""
    k = 1.0 - math.exp(-dt / P[P_REST_TAU])
    follow3(S, _GLP, k, gx, gy, gz)
    g0, g1, g2 = S[_GLP + 1], S[_GLP + 2], S[_GLP + 3]
    d0, d1, d2 = gx - g0, gy - g1, gz - g2
    still = d0 ** 2 + d1 ** 2 + d2 ** 2 < P[P_REST_GYRO_TH] ** 2
    if still:
        still = pymax(pymax(abs(g0), abs(g1)), abs(g2)) < P[P_BIAS_CLIP_CORE]
    if have_a:
        follow3(S, _ALP, k, ax, ay, az)
        if still:
            d0, d1, d2 = ax - S[_ALP + 1], ay - S[_ALP + 2], az - S[_ALP + 3]
            still = d0 ** 2 + d1 ** 2 + d2 ** 2 < P[P_REST_ACC_TH] ** 2
    S[_REST_S] = S[_REST_S] + dt if still else 0.0


rest_step = jit(_rest_step)


def _after_accel_gap(S):
    """``DecoupledKernel._after_accel_gap``: the detectors start again."""
    S[_MISSED] = 0.0
    S[_ALP], S[_ALP + 1], S[_ALP + 2], S[_ALP + 3] = 0.0, 0.0, 0.0, 0.0
    S[_REST_S] = 0.0
    for i in range(3, 7):  # ManoeuvreDetector.restart: mean, mean_sq
        S[_MAN + i] = 0.0
    for i in range(7, 10):  # and its velocity, in part
        S[_MAN + i] *= GAP_VELOCITY_KEPT
    S[_PACE + 2] = 0.0
    S[_LB + 2], S[_LB + 3] = 0.0, 0.0


after_accel_gap = jit(_after_accel_gap)


def _pace_step(S, P, r0, r1, r2, wx, wy, wz, dt):
    """``RotationPace.step`` against the filter's gravity ``acc_i`` (its slot)."""
    if S[_ACCI] == 0.0:
        return 1.0
    gx, gy, gz = S[_ACCI + 1], S[_ACCI + 2], S[_ACCI + 3]
    n_sq = gx * gx + gy * gy + gz * gz
    if n_sq < 1e-18:
        return 1.0
    dx, dy, dz = _G * (r0 - gx), _G * (r1 - gy), _G * (r2 - gz)
    along = (dx * gx + dy * gy + dz * gz) / math.sqrt(n_sq)
    across_sq = pymax(dx * dx + dy * dy + dz * dz - along * along, 0.0)
    w_sq = wx ** 2 + wy ** 2 + wz ** 2
    if S[_PACE + 2] == 0.0:
        S[_PACE], S[_PACE + 1], S[_PACE + 2] = across_sq, w_sq, 1.0
    else:
        tau = P[P_TAU_ACC]
        k = 1.0 - math.exp(-dt / tau)
        S[_PACE] += k * (across_sq - S[_PACE])
        S[_PACE + 1] += k * (w_sq - S[_PACE + 1])
    g_eps_w = _G * P[P_PACE_EPS] * math.sqrt(S[_PACE + 1])
    sigma = pymax(math.sqrt(S[_PACE]), P[P_PACE_FLOOR])
    tau = P[P_TAU_ACC]
    if g_eps_w * tau <= sigma:
        return 1.0
    return g_eps_w * tau / sigma


pace_step = jit(_pace_step)


def _manoeuvre_weight(S, P, r0, r1, r2, dt):
    """``ManoeuvreDetector.weight`` against the filter's gravity ``acc_i``."""
    if S[_ACCI] == 0.0:
        return 1.0
    g0, g1, g2 = S[_ACCI + 1], S[_ACCI + 2], S[_ACCI + 3]
    n = math.sqrt(g0 * g0 + g1 * g1 + g2 * g2)
    if n < 1e-9:
        return 1.0
    u0, u1, u2 = g0 / n, g1 / n, g2 / n
    k_drift = 1.0 - math.exp(-dt / P[P_M_DRIFT_TAU])
    k_mean = 1.0 - math.exp(-dt / P[P_M_WINDOW])
    leak = math.exp(-dt / P[P_M_LEAK])
    e_sq = 0.0
    for i in range(3):
        r = r0 if i == 0 else (r1 if i == 1 else r2)
        gi = g0 if i == 0 else (g1 if i == 1 else g2)
        d = _G * (r - gi)
        S[_MAN + i] += k_drift * (d - S[_MAN + i])
        e = d - S[_MAN + i]
        S[_MAN + 3 + i] += k_mean * (e - S[_MAN + 3 + i])
        S[_MAN + 7 + i] = (S[_MAN + 7 + i] + d * dt) * leak
        e_sq += e * e
    S[_MAN + 6] += k_mean * (e_sq - S[_MAN + 6])
    m0, m1, m2 = S[_MAN + 3], S[_MAN + 4], S[_MAN + 5]
    along = m0 * u0 + m1 * u1 + m2 * u2
    m_sq = m0 * m0 + m1 * m1 + m2 * m2
    across = math.sqrt(pymax(m_sq - along * along, 0.0))
    scatter = math.sqrt(pymax(S[_MAN + 6] - m_sq, 0.0))
    steadiness = across / pymax(scatter, P[P_M_FLOOR])
    v0, v1, v2 = S[_MAN + 7], S[_MAN + 8], S[_MAN + 9]
    speed = math.sqrt(v0 * v0 + v1 * v1 + v2 * v2)
    power = P[P_M_POWER]
    return 1.0 / ((1.0 + (steadiness / P[P_M_RATIO]) ** power)
                  * (1.0 + (speed / P[P_M_SPEED]) ** power))


manoeuvre_weight = jit(_manoeuvre_weight)


# ---------------------------------------------------------------- the look-back
def _entry_dt(L, j):
    return L[j, 3] * L[j, 4] * L[j, 9]


entry_dt = jit(_entry_dt)


def _lb_close(S, P, L, head, count, weight):
    """``LookBack._reweight_recent`` and (no episode yet) ``_start_episode``."""
    cap = L.shape[0]
    lookback_s = P[P_LB_S]
    span = 0.0
    for jj in range(count - 1, -1, -1):
        if span >= lookback_s:
            break
        j = (head + jj) % cap
        L[j, 4] = weight
        span += L[j, 3]
    if S[_LB + 2] == 0.0:
        S[_LB + 2], S[_LB + 3] = 1.0, S[_LB]
        d0, d1, d2 = 0.0, 0.0, 0.0
        for jj in range(count):
            j = (head + jj) % cap
            d0 += L[j, 6] * L[j, 3]
            d1 += L[j, 7] * L[j, 3]
            d2 += L[j, 8] * L[j, 3]
        S[_DV], S[_DV + 1], S[_DV + 2] = d0, d1, d2
        S[_PEAK], S[_PEAK + 1], S[_PEAK + 2] = d0, d1, d2


lb_close = jit(_lb_close)


def _lb_came_back(S, P, i0, i1, i2, dt, rest):
    """``LookBack._came_back``: fold one step into the episode; True when its velocity
    change came back (the episode then ends, as it does beyond the speed bound or after
    the detector's leak time)."""
    S[_LB + 3] += dt
    S[_DV] += i0 * dt
    S[_DV + 1] += i1 * dt
    S[_DV + 2] += i2 * dt
    d0, d1, d2 = S[_DV], S[_DV + 1], S[_DV + 2]
    p0, p1, p2 = S[_PEAK], S[_PEAK + 1], S[_PEAK + 2]
    if d0 * d0 + d1 * d1 + d2 * d2 > p0 * p0 + p1 * p1 + p2 * p2:
        S[_PEAK], S[_PEAK + 1], S[_PEAK + 2] = d0, d1, d2
        p0, p1, p2 = d0, d1, d2
    peak_sq = p0 * p0 + p1 * p1 + p2 * p2
    tol = P[P_LB_TOL]
    back = rest or (peak_sq > tol * tol
                    and d0 * p0 + d1 * p1 + d2 * p2 <= tol * math.sqrt(peak_sq))
    speed = P[P_M_SPEED]
    if back or peak_sq > speed * speed or S[_LB + 3] > P[P_M_LEAK]:
        S[_LB + 2], S[_LB + 3] = 0.0, 0.0
    return back


lb_came_back = jit(_lb_came_back)


def _lb_replay(S, L, head, count, sigma):
    """``LookBack._replay``: the kept input filtered again from the state before it."""
    cap = L.shape[0]
    x = np.empty(3)
    S[_ACCF] = 1.0
    for i in range(6):
        S[_ACCF + 1 + i] = S[_BEFORE + 1 + i]
    for jj in range(count):
        j = (head + jj) % cap
        x[0], x[1], x[2] = L[j, 0], L[j, 1], L[j, 2]
        bw_step(S, _ACCF, x, 3, entry_dt(L, j), sigma)


lb_replay = jit(_lb_replay)


def _lb_trim(S, P, L, head, count, sigma):
    """``LookBack._trim``: only the last ``lookback_s`` kept; what leaves goes into the
    filter before it. Returns the new head and count."""
    cap = L.shape[0]
    x = np.empty(3)
    while S[_LB] > P[P_LB_S] and count > 0:
        S[_LB] -= L[head, 3]
        x[0], x[1], x[2] = L[head, 0], L[head, 1], L[head, 2]
        bw_step(S, _BEFORE, x, 3, entry_dt(L, head), sigma)
        head = (head + 1) % cap
        count -= 1
    return head, count


lb_trim = jit(_lb_trim)


def _lookback_step(S, P, L, a0, a1, a2, dt, weight, base, i0, i1, i2, rest, pace):
    """``LookBack.step`` on the accelerometer filter's slot: returns the weight and
    whether the filter's state was replaced."""
    cap = L.shape[0]
    head, count = int(S[_HEAD]), int(S[_HEAD + 1])
    sigma = 1.0 / P[P_TAU_ACC]
    replaced = False
    closing = weight < 0.5 and S[_LB + 1] >= 0.5
    S[_LB + 1] = weight
    if closing and count > 0 and S[_BEFORE] != 0.0:
        lb_close(S, P, L, head, count, weight)
        replaced = True
    if S[_LB + 2] != 0.0 and lb_came_back(S, P, i0, i1, i2, dt, rest):
        for jj in range(count):
            j = (head + jj) % cap
            L[j, 4] = L[j, 5]
        weight = base
        S[_READM] += 1.0
        replaced = True
    if replaced:
        lb_replay(S, L, head, count, sigma)
    j = (head + count) % cap
    L[j, 0], L[j, 1], L[j, 2], L[j, 3], L[j, 4] = a0, a1, a2, dt, weight
    L[j, 5], L[j, 6], L[j, 7], L[j, 8], L[j, 9] = base, i0, i1, i2, pace
    count += 1
    S[_LB] += dt
    if S[_LB + 2] == 0.0:
        head, count = lb_trim(S, P, L, head, count, sigma)
    S[_HEAD], S[_HEAD + 1] = float(head), float(count)
    return weight, replaced


lookback_step = jit(_lookback_step)


# ---------------------------------------------------------------- inclination, heading
def _inclination_step(S, P, L, ax, ay, az, dt, wx, wy, wz, rest):
    """``DecoupledKernel._inclination_step``: returns the correction (x, y) and the step
    the filter advanced by."""
    a0, a1, a2 = rotate(S[_QG], S[_QG + 1], S[_QG + 2], S[_QG + 3], ax, ay, az)
    pace = 1.0
    if P[P_PACE_ON] != 0.0:
        pace = pace_step(S, P, a0, a1, a2, wx, wy, wz, dt)
    weight = 1.0
    if P[P_MAN_ON] != 0.0:
        if rest:
            for i in range(3, 10):
                if i != 6:
                    S[_MAN + i] = 0.0
        base = weight
        if S[_ACCI] == 0.0:
            n0, n1, n2 = 0.0, 0.0, 0.0
        else:
            n0 = _G * (a0 - S[_ACCI + 1])
            n1 = _G * (a1 - S[_ACCI + 2])
            n2 = _G * (a2 - S[_ACCI + 3])
        mw = manoeuvre_weight(S, P, a0, a1, a2, dt)
        if mw < 0.5:
            weight *= mw
        weight, replaced = lookback_step(
            S, P, L, a0, a1, a2, dt, weight, base, n0 - S[_MAN], n1 - S[_MAN + 1],
            n2 - S[_MAN + 2], rest, pace)
        if replaced:
            S[_ACCI], S[_ACCI + 1], S[_ACCI + 2], S[_ACCI + 3] = \
                1.0, S[_ACCF + 1], S[_ACCF + 2], S[_ACCF + 3]
            qw, qx, qy, qz = S[_QI], S[_QI + 1], S[_QI + 2], S[_QI + 3]
            e0, e1, e2 = rotate(qw, qx, qy, qz, S[_ACCI + 1], S[_ACCI + 2], S[_ACCI + 3])
            w, x, y, z, _, _ = inclination_correction(qw, qx, qy, qz, e0, e1, e2)
            S[_QI], S[_QI + 1], S[_QI + 2], S[_QI + 3] = w, x, y, z
    dt_filter = dt * weight * pace
    if P[P_TAU_REST] > 0.0 and rest:
        dt_filter *= P[P_TAU_ACC] / P[P_TAU_REST]
    x3 = np.empty(3)
    x3[0], x3[1], x3[2] = a0, a1, a2
    bw_step(S, _ACCF, x3, 3, dt_filter, 1.0 / P[P_TAU_ACC])
    S[_ACCI], S[_ACCI + 1], S[_ACCI + 2], S[_ACCI + 3] = \
        1.0, S[_ACCF + 1], S[_ACCF + 2], S[_ACCF + 3]
    qw, qx, qy, qz = S[_QI], S[_QI + 1], S[_QI + 2], S[_QI + 3]
    e0, e1, e2 = rotate(qw, qx, qy, qz, S[_ACCI + 1], S[_ACCI + 2], S[_ACCI + 3])
    w, x, y, z, c0, c1 = inclination_correction(qw, qx, qy, qz, e0, e1, e2)
    S[_QI], S[_QI + 1], S[_QI + 2], S[_QI + 3] = w, x, y, z
    return c0, c1, dt_filter


inclination_step = jit(_inclination_step)


def _heading_step(S, P, mx0, my0, mz0, dt):
    """``DecoupledKernel._heading_step`` (with ``_track_candidate``)."""
    w, x, y, z = qmul(S[_QI], S[_QI + 1], S[_QI + 2], S[_QI + 3],
                      S[_QG], S[_QG + 1], S[_QG + 2], S[_QG + 3])
    mx, my, mz = rotate(w, x, y, z, mx0, my0, mz0)
    norm = math.sqrt(mx * mx + my * my + mz * mz)
    horizontal = hypot2(mx, my)
    if norm < 1e-9 or horizontal < 1e-3 * norm:
        return
    dip = math.atan2(mz, horizontal)
    if S[_MREF] == 0.0:
        S[_MREF], S[_MREF + 1], S[_MREF + 2] = 1.0, norm, dip
    r0, r1 = S[_MREF + 1], S[_MREF + 2]
    th, dip_th = P[P_MAG_NORM_TH], P[P_MAG_DIP_TH_RAD]
    ok = abs(norm - r0) < th * r0 and abs(dip - r1) < dip_th
    S[_MDIST] = 0.0 if ok else 1.0
    if not ok:
        c0, c1 = S[_MCAND + 1], S[_MCAND + 2]
        if S[_MCAND] == 0.0 or not (abs(norm - c0) < th * c0 and abs(dip - c1) < dip_th):
            S[_MCAND], S[_MCAND + 1], S[_MCAND + 2], S[_MCAND_S] = 1.0, norm, dip, 0.0
            return
        k = 1.0 - math.exp(-dt / 1.0)
        S[_MCAND + 1], S[_MCAND + 2] = c0 + k * (norm - c0), c1 + k * (dip - c1)
        S[_MCAND_S] += dt
        if S[_MCAND_S] >= P[P_MAG_NEW]:
            S[_MREF], S[_MREF + 1], S[_MREF + 2] = 1.0, S[_MCAND + 1], S[_MCAND + 2]
            S[_MCAND], S[_MCAND + 1], S[_MCAND + 2], S[_MCAND_S] = 0.0, 0.0, 0.0, 0.0
        return
    S[_MCAND], S[_MCAND + 1], S[_MCAND + 2], S[_MCAND_S] = 0.0, 0.0, 0.0, 0.0
    kr = 1.0 - math.exp(-dt / P[P_MAG_REF_TAU])
    S[_MREF + 1], S[_MREF + 2] = r0 + kr * (norm - r0), r1 + kr * (dip - r1)
    err = wrap(math.atan2(my, mx) + S[_DELTA])
    dz = -(1.0 - math.exp(-dt / P[P_TAU_MAG])) * err
    S[_DELTA] = wrap(S[_DELTA] + dz)


heading_step = jit(_heading_step)


# ---------------------------------------------------------------- one step
def _decoupled_step_kernel(S, P, L, gx, gy, gz, have_a, ax, ay, az, have_m, mx, my, mz, dt):
    """``DecoupledKernel.step``: returns the body -> NED quaternion."""
    bx, by, bz = S[_B], S[_B + 1], S[_B + 2]
    wx, wy, wz = gx - bx, gy - by, gz - bz
    rw, rx, ry, rz = rotvec(wx * dt, wy * dt, wz * dt)
    w, x, y, z = qmul(S[_QG], S[_QG + 1], S[_QG + 2], S[_QG + 3], rw, rx, ry, rz)
    S[_QG], S[_QG + 1], S[_QG + 2], S[_QG + 3] = unit(w, x, y, z)
    if not have_a:
        S[_MISSED] = 1.0
    elif S[_MISSED] != 0.0:
        after_accel_gap(S)
    rest_step(S, P, gx, gy, gz, have_a, ax, ay, az, dt)
    rest = S[_REST_S] >= P[P_REST_MIN]
    if have_a:
        c0, c1, dt_filter = inclination_step(S, P, L, ax, ay, az, dt, wx, wy, wz, rest)
        bias_step(S, P, c0, c1, dt, dt_filter, rest)
    if have_m:
        heading_step(S, P, mx, my, mz, dt)
    half = 0.5 * S[_DELTA]
    w, x, y, z = qmul(S[_QI], S[_QI + 1], S[_QI + 2], S[_QI + 3],
                      S[_QG], S[_QG + 1], S[_QG + 2], S[_QG + 3])
    return qmul(math.cos(half), 0.0, 0.0, math.sin(half), w, x, y, z)


decoupled_step_kernel = jit(_decoupled_step_kernel)


def _decoupled_sample(S, P, L, gx, gy, gz, have_a, ax, ay, az, have_m, mx, my, mz, dt,
                      fx, fy, fz):
    """One step (``have_a``/``have_m`` False: no accelerometer (g, gravity positive) or
    magnetometer this step); returns the quaternion, the gravity-compensated acceleration
    in NED of the measured specific force ``f`` (m/s^2) at it (as
    ``common.ahrs._linear_accel_ned``), whether at rest after the step and whether the
    field was disturbed (the estimate's diagnostics; the bias is in ``S``)."""
    w, x, y, z = decoupled_step_kernel(S, P, L, gx, gy, gz, have_a, ax, ay, az, have_m, mx,
                                       my, mz, dt)
    lx, ly, lz = linear_accel_ned(w, x, y, z, fx, fy, fz)
    return (w, x, y, z, lx, ly, lz, S[_REST_S] >= P[P_REST_MIN], S[_MDIST] != 0.0)


decoupled_sample = per_sample_kernel(jit(
    _decoupled_sample, returns="Tuple((f8, f8, f8, f8, f8, f8, f8, b1, b1))", S="f8[::1]",
    P="f8[::1]", L="f8[:, ::1]", gx="f8", gy="f8", gz="f8", have_a="b1", ax="f8", ay="f8",
    az="f8", have_m="b1", mx="f8", my="f8", mz="f8", dt="f8", fx="f8", fy="f8", fz="f8"))
"""The per-sample kernel (used per sample only on the AOT extension, or forced JIT)."""


def _decoupled_rows(S, P, L, gyro, acc_g, mag, have_mag, dt, bias, cov, disturbed):
    """``DecoupledKernel.step`` per row at a fixed ``dt`` (the offline smoother's causal
    pass, ``DecoupledEstimator._pass``): writes the bias after each row, its covariance
    (row by row) and whether its field was disturbed. Stops early, returning the rows
    done, when the look-back ring is about to fill (the caller grows ``L`` and calls again
    from there)."""
    n = gyro.shape[0]
    cap = L.shape[0]
    for i in range(n):
        if S[_HEAD + 1] + 1.0 >= cap:
            return i
        decoupled_step_kernel(S, P, L, gyro[i, 0], gyro[i, 1], gyro[i, 2], True,
                              acc_g[i, 0], acc_g[i, 1], acc_g[i, 2], have_mag,
                              mag[i, 0], mag[i, 1], mag[i, 2], dt)
        bias[i, 0], bias[i, 1], bias[i, 2] = S[_B], S[_B + 1], S[_B + 2]
        for j in range(9):
            cov[i, j] = S[_BP + j]
        disturbed[i] = S[_MDIST] != 0.0
    return n


decoupled_rows = jit(
    _decoupled_rows, returns="i8", S="f8[::1]", P="f8[::1]", L="f8[:, ::1]",
    gyro="f8[:, ::1]", acc_g="f8[:, ::1]", mag="f8[:, ::1]", have_mag="b1", dt="f8",
    bias="f8[:, ::1]", cov="f8[:, ::1]", disturbed="b1[::1]")
"""The row kernel of the offline passes."""


def _decoupled_block(S, P, L, t_g, gyro, t_a, accel, t_m, mag, mag_block, keep_mag, use_mag,
                     held_mag, held_mag_t, has_held_mag, max_age, last_t, has_last, gyro_fs,
                     accel_fs, nominal_dt, dt_from_ts, max_dt, speed, turn_on, turn_sum, out,
                     diag, dts, lin):
    """A FIFO read's frames in one call, as ``madgwick_block`` takes them (its helpers: the
    common case of ``common/rows.py``'s ``block_rows``, the step lengths, the held or
    stale magnetometer, the turn compensation by the nominal airspeed ``speed``, NaN:
    none), each step ``DecoupledKernel.step``. ``out`` gets the quaternion after each
    step, ``lin`` the gravity-compensated acceleration (NED) of the measured specific
    force, ``diag`` its rest_detected, mag_disturbed (NaN: no magnetometer this step), the
    gyro bias (3) and mag_used. Returns the turn-rate sum, the step lengths that fell back
    to nominal, the stale magnetometer steps and True; or False with nothing written or
    changed (not the common case, or the look-back ring could fill: the frames one by
    one decide)."""
    m = t_g.shape[0]
    if S[_HEAD + 1] + m + 1.0 >= L.shape[0] or not block_case(
            t_g, gyro, t_a, accel, t_m, mag, mag_block, keep_mag, gyro_fs, accel_fs):
        return turn_sum, 0, 0, False
    fallbacks = step_lengths(t_g, last_t, has_last, nominal_dt, dt_from_ts, max_dt, dts)
    mag_rows, stale = mag_rows_kernel(t_g, mag, mag_block, keep_mag, held_mag, held_mag_t,
                                      has_held_mag, max_age)
    fused = nominal_fused(gyro, accel, speed)
    for i in range(m):
        gx, gy, gz = gyro[i, 0], gyro[i, 1], gyro[i, 2]
        if turn_on:
            turn_sum += math.sqrt(gx ** 2 + gy ** 2 + gz ** 2)
        have_m = use_mag and not math.isnan(mag_rows[i, 0])
        w, x, y, z = decoupled_step_kernel(
            S, P, L, gx, gy, gz, True, fused[i, 0] * _TO_G, fused[i, 1] * _TO_G,
            fused[i, 2] * _TO_G, have_m, mag_rows[i, 0], mag_rows[i, 1], mag_rows[i, 2],
            dts[i])
        out[i, 0], out[i, 1], out[i, 2], out[i, 3] = w, x, y, z
        lin[i, 0], lin[i, 1], lin[i, 2] = linear_accel_ned(w, x, y, z, accel[i, 0],
                                                           accel[i, 1], accel[i, 2])
        disturbed = S[_MDIST] != 0.0
        diag[i, 0] = 1.0 if S[_REST_S] >= P[P_REST_MIN] else 0.0
        diag[i, 1] = (1.0 if disturbed else 0.0) if have_m else np.nan
        diag[i, 2], diag[i, 3], diag[i, 4] = S[_B], S[_B + 1], S[_B + 2]
        diag[i, 5] = 1.0 if have_m and not disturbed else 0.0
    return turn_sum, fallbacks, stale, True


decoupled_block = jit(
    _decoupled_block, returns="Tuple((f8, i8, i8, b1))", S="f8[::1]", P="f8[::1]",
    L="f8[:, ::1]", t_g="i8[::1]", gyro="f8[:, ::1]", t_a="i8[::1]", accel="f8[:, ::1]",
    t_m="i8[::1]", mag="f8[:, ::1]", mag_block="b1", keep_mag="b1", use_mag="b1",
    held_mag="f8[::1]", held_mag_t="i8", has_held_mag="b1", max_age="f8", last_t="i8",
    has_last="b1", gyro_fs="f8", accel_fs="f8", nominal_dt="f8", dt_from_ts="b1",
    max_dt="f8", speed="f8", turn_on="b1", turn_sum="f8", out="f8[:, ::1]",
    diag="f8[:, ::1]", dts="f8[::1]", lin="f8[:, ::1]")
"""The block step (the extension, or numba on the first call)."""
