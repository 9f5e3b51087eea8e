"""Orientation errors with BROAD's conventions (Laidig et al. 2021, broad_utils.py).

The error quaternion is expressed in the earth frame, q_err = q_est * q_truth^-1 (both body ->
earth). Its total angle is the total error; its rotation about the vertical axis is the
heading error and the remaining tilt the inclination error (a swing-twist split about the
earth z axis, which is vertical in NED and ENU alike, so the split does not depend on which
of the two the quaternions are in). RMSEs ignore NaN rows, as BROAD's ``rmse`` does, and are
taken over the evaluation mask (BROAD's movement phases).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from imuhal.core.frames import FloatArray


def _unit_rows(q: ArrayLike) -> FloatArray:
    a = np.asarray(q, dtype=float)
    if a.ndim != 2 or a.shape[1] != 4:
        raise ValueError(f"quaternions must be N x 4 (w, x, y, z), got shape {a.shape}")
    return a / np.linalg.norm(a, axis=1)[:, None]


def error_quaternion_earth(q_est: ArrayLike, q_truth: ArrayLike) -> FloatArray:
    """q_est * conj(q_truth), rows normalised: the estimate's error in the earth frame."""
    p, q = _unit_rows(q_est), _unit_rows(q_truth)
    pw, px, py, pz = p.T
    qw, qx, qy, qz = q.T * np.array([[1.0], [-1.0], [-1.0], [-1.0]])
    out = np.stack([
        pw * qw - px * qx - py * qy - pz * qz,
        pw * qx + px * qw + py * qz - pz * qy,
        pw * qy - px * qz + py * qw + pz * qx,
        pw * qz + px * qy - py * qx + pz * qw,
    ], axis=1)
    return out / np.linalg.norm(out, axis=1)[:, None]


def total_error_rad(q_err: FloatArray) -> FloatArray:
    """The error's whole rotation angle (rad), in [0, pi]."""
    return 2.0 * np.arccos(np.clip(np.abs(q_err[:, 0]), 0.0, 1.0))


def heading_error_rad(q_err: FloatArray) -> FloatArray:
    """The error's rotation about the vertical earth axis (rad), in [0, pi]."""
    with np.errstate(divide="ignore", invalid="ignore"):
        return 2.0 * np.arctan(np.abs(q_err[:, 3] / q_err[:, 0]))


def inclination_error_rad(q_err: FloatArray) -> FloatArray:
    """The error's tilt of the vertical axis (rad), in [0, pi]."""
    return 2.0 * np.arccos(np.clip(np.sqrt(q_err[:, 0] ** 2 + q_err[:, 3] ** 2), 0.0, 1.0))


def rms(values: FloatArray) -> float:
    """Root mean square over the finite-or-NaN values, NaN ignored (NaN if all are NaN)."""
    v = np.asarray(values, dtype=float)
    if v.size == 0 or np.all(np.isnan(v)):
        return float("nan")
    return float(np.sqrt(np.nanmean(v ** 2)))


@dataclass(frozen=True)
class Errors:
    """RMS errors in degrees over the evaluated samples."""

    total_deg: float
    heading_deg: float
    inclination_deg: float
    evaluated: int
    """Samples in the mask that had an estimate."""
    missing: int
    """Samples in the mask without an estimate (NaN rows): never counted as correct."""


def rmse_deg(q_est: ArrayLike, q_truth: ArrayLike, mask: ArrayLike | None = None) -> Errors:
    """BROAD's calculateRMSE: total, heading and inclination RMSE (deg) over ``mask``."""
    q_err = error_quaternion_earth(q_est, q_truth)
    m = np.ones(len(q_err), bool) if mask is None else np.asarray(mask, dtype=bool)
    if m.shape != (len(q_err),):
        raise ValueError(f"mask must have {len(q_err)} entries, got shape {m.shape}")
    sel = q_err[m]
    missing = int(np.isnan(sel[:, 0]).sum())
    return Errors(
        total_deg=float(np.rad2deg(rms(total_error_rad(sel)))),
        heading_deg=float(np.rad2deg(rms(heading_error_rad(sel)))),
        inclination_deg=float(np.rad2deg(rms(inclination_error_rad(sel)))),
        evaluated=int(len(sel) - missing),
        missing=missing,
    )
