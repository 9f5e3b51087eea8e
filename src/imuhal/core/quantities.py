"""Physical quantities as descriptors: a name, an SI unit and a shape.

A quantity is what a sample measures. imuhal's own are the class attributes of
:class:`Quantity` (``Quantity.ACCEL`` ...). A plugin adds one without touching core: it
creates a ``Quantity``, a sample class whose ``channel`` is it, and registers that sample
class through the ``imuhal_register_quantities`` hook (docs/writing-a-driver.md).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, ClassVar

_INTERNED: dict[tuple[Any, ...], Quantity] = {}
"""Every valid quantity made so far, by its fields (see :class:`Quantity`)."""


@dataclass(frozen=True, slots=True, eq=False)
class Quantity:
    """A physical quantity a device provides, with its unit at the pipeline boundary.

    ``name`` is stable (profiles, CSV ``kind`` column, calibration keys); ``shape`` is ``()``
    for a scalar and ``(3,)`` for a three-axis vector in a frame.

    Quantities are interned: making one with the fields of one made before gives that one
    (also through ``copy`` and ``pickle``), so equal quantities are the same object, and
    equality and hashing are object identity's, in C. Quantities key dicts on every
    sample's path (full scales, last valid times, fusion ranks, data-ready times: about 19
    look-ups per IMU sample on the hardware path); a hash written in Python cost a Python
    call at each (docs/performance.md, "The hardware path's per-poll costs").
    """

    name: str
    unit: str
    shape: tuple[int, ...] = ()
    description: str = ""

    ACCEL: ClassVar[Quantity]
    GYRO: ClassVar[Quantity]
    MAG: ClassVar[Quantity]
    PRESSURE: ClassVar[Quantity]
    TEMPERATURE: ClassVar[Quantity]
    VELOCITY: ClassVar[Quantity]
    AIRSPEED: ClassVar[Quantity]
    POSITION: ClassVar[Quantity]

    def __new__(cls, name: str, unit: str, shape: tuple[int, ...] = (),
                description: str = "") -> Quantity:
        try:
            made = _INTERNED.get((cls, name, unit, shape, description))
        except TypeError:  # an unhashable field: __post_init__ says what is wrong
            made = None
        return made if made is not None else object.__new__(cls)

    def __post_init__(self) -> None:
        if not self.name.isidentifier() or self.name != self.name.lower():
            raise ValueError(f"quantity name {self.name!r} must be a lower-case identifier")
        if self.shape not in ((), (3,)):
            raise ValueError(f"quantity {self.name!r}: shape must be () (scalar) or (3,) "
                             f"(three-axis vector), not {self.shape}")
        _INTERNED.setdefault(self._fields(), self)

    def _fields(self) -> tuple[Any, ...]:
        return (type(self), self.name, self.unit, self.shape, self.description)

    def __reduce__(self) -> tuple[Any, ...]:
        # copies and unpickled quantities made through __new__: the interned one
        return (type(self), self._fields()[1:])

    @property
    def value(self) -> str:
        """The name (``"accel"``, ...)."""
        return self.name

    @property
    def is_vector(self) -> bool:
        return self.shape == (3,)

    def __str__(self) -> str:
        return self.name


Quantity.ACCEL = Quantity(
    "accel", "m/s^2", (3,),
    "Specific force (a level board at rest reads (0, 0, -9.81) in NED).")
Quantity.GYRO = Quantity("gyro", "rad/s", (3,), "Angular rate, right-handed about each axis.")
Quantity.MAG = Quantity("mag", "uT", (3,), "Magnetic flux density.")
Quantity.PRESSURE = Quantity("pressure", "Pa", (), "Static pressure.")
Quantity.TEMPERATURE = Quantity("temperature", "degC", (), "Die temperature.")
Quantity.VELOCITY = Quantity(
    "velocity", "m/s", (3,),
    "Velocity over ground in NED (north, east, down), e.g. from a GNSS receiver.")
Quantity.AIRSPEED = Quantity(
    "airspeed", "m/s", (), "True airspeed along the body x axis, e.g. from a pitot tube.")

Quantity.POSITION = Quantity(
    "position", "deg, deg, m", (3,),
    "Geodetic position: latitude and longitude in degrees (WGS-84), height in m; three "
    "values, not a vector in a frame (no mount rotation applies).")
