"""What the simulated world hands a chip: the true physical quantities at it."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import Any

from imuhal.core.samples import slot_setter

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
_set_force = slot_setter(PhysicalInputs, "specific_force_m_s2")
_set_rate = slot_setter(PhysicalInputs, "angular_rate_rad_s")
_set_field = slot_setter(PhysicalInputs, "magnetic_field_ut")
_set_pressure = slot_setter(PhysicalInputs, "pressure_pa")
_set_temperature = slot_setter(PhysicalInputs, "temperature_degc")
_set_position = slot_setter(PhysicalInputs, "position_ned_m")
_set_velocity = slot_setter(PhysicalInputs, "velocity_ned_m_s")
_set_other = slot_setter(PhysicalInputs, "other")
