"""Estimating the barometer's altitude noise variance the way the seed advises."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

MIN_SAMPLES = 10
MAX_WINDOW_S = 5.0


def estimate_altitude_variance(
    altitudes_m: Sequence[float] | np.ndarray, sample_rate_hz: float
) -> float:
    """sigma_zmeas^2 (m^2): the sample variance of 1-2 s of barometric altitude at rest.

    Take the altitudes at the normal sampling rate with the unit still. Longer windows are
    refused: over more than a few seconds the real pressure drifts enough to inflate the
    variance (the seed: "Do not use longer intervals"), so more than 5 s of data (judged from
    ``sample_rate_hz``) raises ValueError, as do fewer than 10 samples (too few for a variance
    worth tuning with). Multiply by 1e4 for the cm^2 the kf3 core uses.
    """
    z = np.asarray(altitudes_m, dtype=float).ravel()
    if z.size < MIN_SAMPLES:
        raise ValueError(
            f"need at least {MIN_SAMPLES} altitude samples to estimate their variance, got "
            f"{z.size}; record 1-2 s at the normal barometer rate"
        )
    if not sample_rate_hz > 0:
        raise ValueError(f"sample_rate_hz must be positive, got {sample_rate_hz}")
    duration = z.size / sample_rate_hz
    if duration > MAX_WINDOW_S:
        raise ValueError(
            f"{z.size} samples at {sample_rate_hz} Hz span {duration:.1f} s; use 1-2 s "
            f"(at most {MAX_WINDOW_S:.0f} s): over longer windows the barometric pressure "
            "itself drifts and inflates the variance"
        )
    if not np.all(np.isfinite(z)):
        raise ValueError("altitudes contain NaN or infinite values; drop flagged samples first")
    return float(np.var(z, ddof=1))
