"""Helpers for driver settings declared as tables (physical value -> register code)."""

from __future__ import annotations

import math
import numbers
import types
import typing
from collections.abc import Mapping
from dataclasses import dataclass
from enum import Enum
from typing import Annotated, Any, Literal

from pydantic import AfterValidator, BaseModel, BeforeValidator, ValidationInfo

from imuhal.bus.auto_read import AUTO_READ


def pick(table: Mapping[float, object], value: float, name: str, unit: str) -> float:
    """The key of ``table`` equal to ``value`` (floats compared to 1e-9), or a ValueError
    listing the allowed values, which pydantic turns into a located profile error."""
    for key in table:
        if math.isclose(float(key), float(value), rel_tol=1e-9, abs_tol=1e-12):
            return key
    allowed = ", ".join(f"{k:g}" for k in sorted(table))
    raise ValueError(f"{name} = {value:g} {unit} is not supported; allowed: {allowed} {unit}")


@dataclass(frozen=True)
class Allowed:
    """Field metadata: the values a table-backed setting accepts (see ``table_setting``)."""

    values: tuple[Any, ...]


def table_setting(table: Mapping[Any, object], unit: str, *, kind: type = float,
                  label: str = "") -> Any:
    """A settings field type accepting exactly the keys of a register table.

    ``gyro_odr_hz: table_setting(GYRO_ODR_HZ, "Hz") = 250`` validates against the table
    (floats compared to 1e-9), names the allowed values in its error, and reports them in
    ``DriverSettings.choices()`` without any further code.
    """

    def check(value: Any, info: Any) -> Any:
        name = label or info.field_name
        if isinstance(value, bool) or not isinstance(value, numbers.Real):
            # strict like every other number in a profile: true is not 1, "500" is not 500
            allowed = ", ".join(f"{k:g}" if isinstance(k, int | float) else str(k)
                                for k in sorted(table))
            raise ValueError(f"{name} must be a number in {unit}; allowed: {allowed} {unit}")
        return kind(pick(table, float(value), name, unit))

    return Annotated[kind, BeforeValidator(check), Allowed(tuple(table))]


def literal_choices(model: type[BaseModel]) -> dict[str, tuple[Any, ...]]:
    """The allowed values of every Literal, Enum or table-backed field of ``model``."""
    out: dict[str, tuple[Any, ...]] = {}
    for name, field in model.model_fields.items():
        allowed = next((m for m in field.metadata if isinstance(m, Allowed)), None)
        if allowed is not None:
            out[name] = allowed.values
            continue
        annotation = field.annotation
        if typing.get_origin(annotation) in (typing.Union, types.UnionType):
            args = [a for a in typing.get_args(annotation) if a is not type(None)]
            annotation = args[0] if len(args) == 1 else annotation
        if typing.get_origin(annotation) is typing.Literal:
            out[name] = typing.get_args(annotation)
        elif isinstance(annotation, type) and issubclass(annotation, Enum):
            out[name] = tuple(annotation)
    return out


BUS_CONTEXT = "bus"
"""Validation context key (profile loader): the bus reference a device sits on."""
BUS_FEATURES_CONTEXT = "bus_features"
"""Validation context key: the features of that bus (``Driver.child_bus_features``; a bus
a profile opens itself has none). Absent when settings are validated without a profile."""


def _auto_read_possible(value: str, info: ValidationInfo) -> str:
    context = info.context if isinstance(info.context, dict) else {}
    features = context.get(BUS_FEATURES_CONTEXT)
    if value == "auto" and features is not None and AUTO_READ not in features:
        bus = context.get(BUS_CONTEXT, "this bus")
        raise ValueError(
            f"'auto' needs a bus whose master reads the chip on its own (slave auto-read, "
            f"e.g. the MAX21100's imu/aux or an MPU-9250's with aux: master); bus {bus!r} "
            "cannot: use read: one-shot")
    return value


SlaveRead = Annotated[Literal["one-shot", "auto"], AfterValidator(_auto_read_possible)]
"""The ``read`` setting of a chip that can sit behind an I2C master: ``one-shot``, the
driver reads the chip with its own transactions; ``auto``, the master reads the chip's data
registers on its own and the driver takes them from the master's burst (imuhal.bus.auto_read).
A profile that asks for ``auto`` on a bus without the feature is refused with a located
one-line error; a driver built directly raises ConfigurationError at construction."""
