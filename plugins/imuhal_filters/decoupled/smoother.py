"""Offline smoothing for the "decoupled" estimator: the whole recording known in advance.

A mean of a forward and a backward attitude is not a smoother: each pass's errors (the
accelerometer filter's delay, a bias learnt late, a disturbance noticed late) are averaged,
not removed. This follows the structure of offline VQF (Laidig and Seel 2023) instead:
every state is estimated from both directions first, then the attitude is built once.

1. **Bias**: the online filter runs forwards and, on the time-reversed recording (gyro
   negated), backwards; at every sample the two Kalman estimates of the gyro bias are fused
   by their information (P^-1), so the bias at any instant uses the rest phases and motion
   on both sides of it.
2. **Strapdown**: the gyro minus that bias is integrated once from the aligned start.
3. **Inclination**: the accelerometer, rotated into the strapdown frame, is low-pass filtered
   forwards and then backwards (zero phase: no delay), and the inclination correction turns
   the filtered vector to the vertical at each sample.
4. **Heading**: the magnetometer's heading in the corrected frame is filtered forwards and
   backwards with ``tau_mag_s``. A sample both passes flagged as magnetically disturbed is
   not fused, nor is one in a short undisturbed stretch or near a disturbance
   (``clean_field``); the others are fused with a gain weighted by how close the field's
   norm and dip are to the reference learnt over the whole recording (``field_weights``):
   the heading drifts most while a magnet approaches, before the check flags it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from imuhal.core.frames import FloatArray
from imuhal_filters.common.quat import IDENTITY, Quat, multiply, to_global
from imuhal_filters.decoupled.bias import fuse
from imuhal_filters.decoupled.core import (
    ButterworthLowPass,
    _rotvec_quat,
    _unit_quat,
    _wrap,
    inclination_correction,
)


@dataclass
class PassRecord:
    """What one causal pass learnt at each sample (forward time order)."""

    bias_rad_s: FloatArray
    """(N, 3) bias estimate, body axes."""
    information: FloatArray
    """(N, 3, 3) P^-1 of the bias estimate, (deg/s)^-2."""
    mag_disturbed: np.ndarray
    """(N,) bool."""


def fused_bias(fwd: PassRecord, bwd: PassRecord) -> FloatArray:
    """(N, 3) information-weighted bias of the two passes."""
    out = np.empty_like(fwd.bias_rad_s)
    for i in range(out.shape[0]):
        b, _ = fuse(tuple(fwd.bias_rad_s[i]), fwd.information[i].tolist(),
                    tuple(bwd.bias_rad_s[i]), bwd.information[i].tolist())
        out[i] = b
    return out


def strapdown(q0: Quat, gyro_rad_s: FloatArray, bias_rad_s: FloatArray, dt: float) -> FloatArray:
    """(N, 4) attitudes integrated from ``q0`` (row 0) with the gyro minus the bias."""
    n = gyro_rad_s.shape[0]
    out = np.empty((n, 4))
    q = q0
    w = (gyro_rad_s - bias_rad_s) * dt
    out[0] = q
    for i in range(1, n):
        x, y, z = w[i]
        q = _unit_quat(multiply(q, _rotvec_quat(float(x), float(y), float(z))))
        out[i] = q
    return out


def zero_phase(x: FloatArray, tau_s: float, dt: float) -> FloatArray:
    """The low-pass run forwards, then backwards over its output: (N, k) -> (N, k)."""
    out = np.empty_like(x)
    for rows in (range(x.shape[0]), range(x.shape[0] - 1, -1, -1)):
        f = ButterworthLowPass(tau_s)
        src = x if rows.start == 0 else out
        for i in rows:
            out[i] = f.step(tuple(src[i]), dt)
    return out


def rotate_rows(q: FloatArray, v: FloatArray) -> FloatArray:
    """Each row of v (N, 3) rotated by the matching quaternion (local -> global)."""
    w, x, y, z = q[:, 0:1], q[:, 1:2], q[:, 2:3], q[:, 3:4]
    u = np.concatenate([x, y, z], axis=1)
    t = 2.0 * np.cross(u, v)
    return v + w * t + np.cross(u, t)


def inclination(q_gyro: FloatArray, acc_i: FloatArray) -> FloatArray:
    """(N, 4) attitudes q_inc * q_gyro: q_inc turns each filtered vector ``acc_i`` (the
    accelerometer in the strapdown frame) to the vertical, as the online filter does."""
    out = np.empty_like(q_gyro)
    q_inc: Quat = IDENTITY
    for i in range(q_gyro.shape[0]):
        e = to_global(q_inc, (float(acc_i[i, 0]), float(acc_i[i, 1]), float(acc_i[i, 2])))
        q_inc = inclination_correction(q_inc, e)[0]
        out[i] = multiply(q_inc, tuple(q_gyro[i]))
    return out


def clean_field(disturbed: np.ndarray, min_clean_s: float, margin_s: float,
                dt: float) -> np.ndarray:
    """(N,) bool: the samples whose field is trusted offline. A field is trusted only inside
    an undisturbed stretch of at least ``min_clean_s`` and not within ``margin_s`` of a
    disturbance: near a magnet a few readings pass the norm and dip check by chance (the
    field sweeps through the reference's values), and the field already deviates, below
    the thresholds, before and after the stretch the check flags. The recording's own ends
    are not disturbances (no margin there)."""
    use = ~np.asarray(disturbed, dtype=bool)
    out = np.zeros_like(use)
    n_min, n_margin = round(min_clean_s / dt), round(margin_s / dt)
    edges = np.diff(np.concatenate([[0], use.astype(np.int8), [0]]))
    for a, b in zip(np.flatnonzero(edges == 1), np.flatnonzero(edges == -1), strict=True):
        if b - a < max(n_min, 1):
            continue
        a2 = a + n_margin if a > 0 else a
        b2 = b - n_margin if b < use.shape[0] else b
        if b2 > a2:
            out[a2:b2] = True
    return out


def field_weights(m: FloatArray, trusted: np.ndarray, norm_th: float,
                  dip_th_rad: float) -> FloatArray:
    """(N,) heading gain weights in [0, 1] for the field ``m`` in the inclination-corrected
    frame: 0 where not ``trusted``, else 1 / (1 + (norm deviation / (norm_th * ref))^2 +
    (dip deviation / dip_th_rad)^2), the reference being the median norm and dip of the
    trusted samples of the whole recording (offline: the field's undisturbed value is
    known from both sides). A field close to the reference is trusted in full, one near
    the detector's thresholds at a third."""
    norm = np.linalg.norm(m, axis=1)
    dip = np.arctan2(m[:, 2], np.hypot(m[:, 0], m[:, 1]))
    w = np.zeros(m.shape[0])
    if not trusted.any():
        return w
    ref_norm, ref_dip = float(np.median(norm[trusted])), float(np.median(dip[trusted]))
    x = ((norm - ref_norm) / (norm_th * ref_norm)) ** 2 + ((dip - ref_dip) / dip_th_rad) ** 2
    w[trusted] = 1.0 / (1.0 + x[trusted])
    return w


def heading(q6: FloatArray, mag: FloatArray, weight: FloatArray, tau_mag_s: float,
            dt: float) -> FloatArray:
    """(N,) heading correction delta (rad) about the NED vertical, zero phase: each
    sample's gain is the filter's (time constant ``tau_mag_s``) times its ``weight``
    (0: not fused, the correction held)."""
    m = rotate_rows(q6, mag)
    raw = -np.arctan2(m[:, 1], m[:, 0])
    w = np.where(np.isfinite(raw) & (np.hypot(m[:, 0], m[:, 1]) > 1e-3 *
                                     np.linalg.norm(m, axis=1)), weight, 0.0)
    use = w > 0.0
    n = raw.shape[0]
    delta = np.zeros(n)
    if not use.any():
        return delta
    k = 1.0 - math.exp(-dt / tau_mag_s)
    d = float(raw[np.argmax(use)])
    gains = (k * w).tolist()
    raws = raw.tolist()
    for i in range(n):  # forwards
        if gains[i] > 0.0:
            d = _wrap(d + gains[i] * _wrap(raws[i] - d))
        delta[i] = d
    for i in range(n - 1, -1, -1):  # backwards over the forward result
        if gains[i] > 0.0:
            d = _wrap(d + gains[i] * _wrap(float(delta[i]) - d))
        delta[i] = d
    return delta


def apply_heading(q6: FloatArray, delta: FloatArray) -> FloatArray:
    """(N, 4) rotations about the NED vertical by ``delta`` applied to ``q6``."""
    h = np.zeros_like(q6)
    h[:, 0], h[:, 3] = np.cos(0.5 * delta), np.sin(0.5 * delta)
    w1, x1, y1, z1 = (h[:, i] for i in range(4))
    w2, x2, y2, z2 = (q6[:, i] for i in range(4))
    return np.stack([w1 * w2 - x1 * x2 - y1 * y2 - z1 * z2,
                     w1 * x2 + x1 * w2 + y1 * z2 - z1 * y2,
                     w1 * y2 - x1 * z2 + y1 * w2 + z1 * x2,
                     w1 * z2 + x1 * y2 - y1 * x2 + z1 * w2], axis=1)

