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


class PlannedInputs:
    """The inputs of a chip's coming pulls computed ahead (an emulated board's plan: the
    instants a chip with its own clock announced), as arrays: row i is what the i-th pull
    is handed, in the chip's sensor frame and SI units. ``specific_force_m_s2``,
    ``angular_rate_rad_s`` and ``magnetic_field_ut`` are (n, 3), ``pressure_pa`` and
    ``temperature_degc`` (n,) float64 arrays; ``position_ned_m`` and ``velocity_ned_m_s``
    (n, 3), earth frame, as in :class:`PhysicalInputs`. No quantity outside imuhal's
    (``other``) is planned.

    An emulator may encode a quantity for every row at once (its counts for the plan in one
    numpy pass, by the operations it applies to one value); :meth:`row` is the same
    :class:`PhysicalInputs` a pull by pull hand-over would give."""

    __slots__ = ("angular_rate_rad_s", "magnetic_field_ut", "position_ned_m", "pressure_pa",
                 "specific_force_m_s2", "temperature_degc", "velocity_ned_m_s")

    def __init__(self, specific_force_m_s2: Any, angular_rate_rad_s: Any,
                 magnetic_field_ut: Any, pressure_pa: Any, temperature_degc: Any,
                 position_ned_m: Any, velocity_ned_m_s: Any) -> None:
        self.specific_force_m_s2 = specific_force_m_s2
        self.angular_rate_rad_s = angular_rate_rad_s
        self.magnetic_field_ut = magnetic_field_ut
        self.pressure_pa = pressure_pa
        self.temperature_degc = temperature_degc
        self.position_ned_m = position_ned_m
        self.velocity_ned_m_s = velocity_ned_m_s

    def __len__(self) -> int:
        return len(self.pressure_pa)

    def row(self, i: int) -> PhysicalInputs:
        """The inputs of the i-th planned pull (Python floats, as ``tolist`` gives them)."""
        return PhysicalInputs.build(
            tuple(self.specific_force_m_s2[i].tolist()),
            tuple(self.angular_rate_rad_s[i].tolist()),
            tuple(self.magnetic_field_ut[i].tolist()), self.pressure_pa[i].item(),
            self.temperature_degc[i].item(), tuple(self.position_ned_m[i].tolist()),
            tuple(self.velocity_ned_m_s[i].tolist()), NO_OTHER)
