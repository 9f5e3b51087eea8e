"""Coverage of directions on the unit sphere: how much of the sphere a set of vectors visits.

The sphere is cut into ``bands x sectors`` cells of equal area (bands equally spaced in z,
sectors equally spaced in azimuth). Coverage is the fraction of cells holding at least
``min_per_cell`` vectors. A figure of 8 in three dimensions reaches 80-90 %; holding the
board level while turning it only reaches a belt of cells (about 30 %).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from imuhal.core.frames import FloatArray

AXIS_NAMES = ("+x", "-x", "+y", "-y", "+z", "-z")
_AXES = np.array([[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]], float)


@dataclass(frozen=True)
class Coverage:
    fraction: float
    """Fraction of equal-area cells visited (0..1)."""
    cells: int
    missing_axes: tuple[str, ...]
    """Sensor axes (``+x`` .. ``-z``) with no vector within 45 degrees of them."""


def coverage(vectors: FloatArray, *, bands: int = 6, sectors: int = 12,
             min_per_cell: int = 2) -> Coverage:
    """Coverage of the directions of ``vectors`` (N x 3, any length, zero rows ignored)."""
    v = np.asarray(vectors, dtype=float).reshape(-1, 3)
    n = np.linalg.norm(v, axis=1)
    u = v[n > 0] / n[n > 0, None]
    counts = np.zeros((bands, sectors), dtype=int)
    if len(u):
        zb = np.clip(((u[:, 2] + 1.0) / 2.0 * bands).astype(int), 0, bands - 1)
        az = np.arctan2(u[:, 1], u[:, 0])
        sb = np.clip(((az + np.pi) / (2 * np.pi) * sectors).astype(int), 0, sectors - 1)
        np.add.at(counts, (zb, sb), 1)
    seen = (u @ _AXES.T).max(axis=0) if len(u) else np.full(6, -1.0)
    missing = tuple(name for name, c in zip(AXIS_NAMES, seen, strict=True)
                    if c < np.cos(np.radians(45)))
    return Coverage(float(np.mean(counts >= min_per_cell)), bands * sectors, missing)
