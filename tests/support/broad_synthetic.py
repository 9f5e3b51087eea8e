"""A tiny synthetic recording in BROAD's file format (never BROAD's data).

The sensor turns at a constant rate about a tilted axis; gyro, accelerometer (specific force,
+9.81 m/s^2 up at rest, sensor axes) and magnetometer are exact apart from seeded white
noise, and ``opt_quat`` is the true sensor -> ENU quaternion, as in BROAD's files.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

RATE_HZ = 285.7142857142857
FIELD_ENU_UT = np.array([0.0, 20.0, -40.0])
"""A northern-hemisphere field in ENU (north and down components)."""


def _qmul(p: np.ndarray, q: np.ndarray) -> np.ndarray:
    pw, px, py, pz = p
    qw, qx, qy, qz = q
    return np.array([pw * qw - px * qx - py * qy - pz * qz, pw * qx + px * qw + py * qz - pz * qy,
                     pw * qy - px * qz + py * qw + pz * qx, pw * qz + px * qy - py * qx + pz * qw])


def _rotate_inverse(q: np.ndarray, v: np.ndarray) -> np.ndarray:
    """q* v q: an earth vector in the sensor frame."""
    w, x, y, z = q
    r = np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                  [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                  [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])
    return r.T @ v


def synthetic_trial(seconds: float = 4.0, seed: int = 1, noise: float = 0.002) -> dict:
    """Arrays and rate of one trial (keys as in BROAD's files)."""
    rng = np.random.default_rng(seed)
    n = round(seconds * RATE_HZ)
    dt = 1.0 / RATE_HZ
    q = np.array([np.cos(0.15), np.sin(0.15), 0.0, 0.0])  # tilted start
    rate = np.array([0.3, -0.2, 0.5])  # rad/s, sensor frame
    gyr, acc, mag, quat = (np.zeros((n, 3)), np.zeros((n, 3)), np.zeros((n, 3)),
                           np.zeros((n, 4)))
    half = rate * dt / 2
    angle = np.linalg.norm(half)
    dq = np.r_[np.cos(angle), np.sin(angle) * half / angle]
    for i in range(n):
        moving = n // 4 < i < 3 * n // 4  # rest, motion, rest
        w = rate if moving else np.zeros(3)
        quat[i] = q
        gyr[i] = w + rng.normal(0, noise, 3)
        acc[i] = _rotate_inverse(q, np.array([0.0, 0.0, 9.81])) + rng.normal(0, noise * 10, 3)
        mag[i] = _rotate_inverse(q, FIELD_ENU_UT) + rng.normal(0, noise * 50, 3)
        if moving:
            q = _qmul(q, dq)
            q /= np.linalg.norm(q)
    movement = np.zeros(n, bool)
    movement[n // 8:] = True
    return {"imu_gyr": gyr, "imu_acc": acc, "imu_mag": mag, "opt_quat": quat,
            "opt_pos": np.zeros((n, 3)), "movement": movement, "sampling_rate": RATE_HZ}


def write_trials_json(folder: Path, names: dict[str, list[str]]) -> None:
    groups = sorted({g for gs in names.values() for g in gs})
    info = {"groups": [{"name": g} for g in groups],
            "trials": {name: {"groups": gs} for name, gs in names.items()}}
    (folder / "trials.json").write_text(json.dumps(info), encoding="utf-8")


def write_hdf5(path: Path, trial: dict) -> Path:
    import h5py

    with h5py.File(path, "w") as f:
        for k, v in trial.items():
            if k == "sampling_rate":
                f.attrs["sampling_rate"] = v
            else:
                f.create_dataset(k, data=v)
    return path


def write_mat(path: Path, trial: dict) -> Path:
    import scipy.io

    scipy.io.savemat(path, {k: (np.array([[v]]) if k == "sampling_rate" else v)
                            for k, v in trial.items()})
    return path
