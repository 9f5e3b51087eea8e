"""What the simulated world hands a chip: the true physical quantities at it."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import Any

NO_OTHER: Mapping[str, Any] = MappingProxyType({})
"""The shared empty mapping of quantities imuhal does not model."""


@dataclass(frozen=True, slots=True)
class PhysicalInputs:
    """True physical quantities at the chip, in its own sensor frame. None: not simulated."""

    specific_force_m_s2: tuple[float, float, float] | None = None
    angular_rate_rad_s: tuple[float, float, float] | None = None
    magnetic_field_ut: tuple[float, float, float] | None = None
    pressure_pa: float | None = None
    temperature_degc: float | None = None
    position_ned_m: tuple[float, float, float] | None = None
    """Earth-frame position relative to the scenario origin (NED, m): not rotated into the
    chip's frame (a GNSS receiver reports where the board is, not how it is mounted)."""
    velocity_ned_m_s: tuple[float, float, float] | None = None
    """Earth-frame velocity over ground (NED, m/s), likewise not rotated."""
    other: Mapping[str, float | tuple[float, float, float]] = field(
        default_factory=lambda: NO_OTHER)
    """Quantities imuhal does not model, by quantity name, as a plugin's scenario provides
    them (``TruthState.other``): scalars, and 3-vectors in the chip's sensor frame."""
