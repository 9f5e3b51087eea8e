"""What the simulated world hands a chip: the true physical quantities at it."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import Any

NO_OTHER: Mapping[str, Any] = MappingProxyType({})
"""The shared empty mapping of quantities imuhal does not model."""

Vec3 = tuple[float, float, float]


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

    @classmethod
    def build(cls, force: Vec3 | None, rate: Vec3 | None, field: Vec3 | None,
              pressure: float | None, temperature: float | None, position: Vec3 | None,
              velocity: Vec3 | None, other: Mapping[str, float | Vec3]) -> PhysicalInputs:
        """The same inputs as the keyword constructor with every field given, in field
        order, built faster (an emulated board builds one per chip and poll): the fields are
        set through their slots, where the generated ``__init__`` of a frozen class goes
        through ``object.__setattr__`` per field. No field is checked or converted by either
        way."""
        s = _new(cls)
        _set_force(s, force)
        _set_rate(s, rate)
        _set_field(s, field)
        _set_pressure(s, pressure)
        _set_temperature(s, temperature)
        _set_position(s, position)
        _set_velocity(s, velocity)
        _set_other(s, other)
        return s


_new = object.__new__
_set_force = PhysicalInputs.specific_force_m_s2.__set__  # type: ignore[attr-defined]
_set_rate = PhysicalInputs.angular_rate_rad_s.__set__  # type: ignore[attr-defined]
_set_field = PhysicalInputs.magnetic_field_ut.__set__  # type: ignore[attr-defined]
_set_pressure = PhysicalInputs.pressure_pa.__set__  # type: ignore[attr-defined]
_set_temperature = PhysicalInputs.temperature_degc.__set__  # type: ignore[attr-defined]
_set_position = PhysicalInputs.position_ned_m.__set__  # type: ignore[attr-defined]
_set_velocity = PhysicalInputs.velocity_ned_m_s.__set__  # type: ignore[attr-defined]
_set_other = PhysicalInputs.other.__set__  # type: ignore[attr-defined]
