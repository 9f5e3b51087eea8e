"""What the simulated world hands a chip: the true physical quantities at it."""

from __future__ import annotations

from dataclasses import dataclass


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
