"""Turning a PressureSample into a fusable altitude, shared by both vario estimators."""

from __future__ import annotations

import math

from imuhal.core.atmosphere import altitude_m_from_pressure
from imuhal.core.samples import PressureSample

NS_PER_S = 1_000_000_000


def usable_altitude_m(sample: PressureSample, sea_level_pa: float) -> float | None:
    """ISA altitude (m, up +) of a pressure sample, or None if it must not be fused.

    None when the sample is flagged (``.valid`` is False) or when its pressure is not a
    positive finite number (a driver that forgot to flag it must not crash the filter).
    """
    if not sample.valid:
        return None
    p = sample.pressure_pa
    if not (math.isfinite(p) and p > 0.0):
        return None
    return altitude_m_from_pressure(p, sea_level_pa)


def dt_s(t_ns: int, prev_t_ns: int) -> float:
    """Seconds between two pipeline timestamps (int ns)."""
    return (t_ns - prev_t_ns) / NS_PER_S
