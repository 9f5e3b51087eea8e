"""Helpers for driver settings declared as tables (physical value -> register code)."""

from __future__ import annotations

import math
import types
import typing
from collections.abc import Mapping
from enum import Enum
from typing import Any

from pydantic import BaseModel


def pick(table: Mapping[float, object], value: float, name: str, unit: str) -> float:
    """The key of ``table`` equal to ``value`` (floats compared to 1e-9), or a ValueError
    listing the allowed values, which pydantic turns into a located profile error."""
    for key in table:
        if math.isclose(float(key), float(value), rel_tol=1e-9, abs_tol=1e-12):
            return key  # type: ignore[return-value]
    allowed = ", ".join(f"{k:g}" for k in sorted(table))
    raise ValueError(f"{name} = {value:g} {unit} is not supported; allowed: {allowed} {unit}")


def literal_choices(model: type[BaseModel]) -> dict[str, tuple[Any, ...]]:
    """The allowed values of every Literal or Enum field of ``model``."""
    out: dict[str, tuple[Any, ...]] = {}
    for name, field in model.model_fields.items():
        annotation = field.annotation
        if typing.get_origin(annotation) in (typing.Union, types.UnionType):
            args = [a for a in typing.get_args(annotation) if a is not type(None)]
            annotation = args[0] if len(args) == 1 else annotation
        if typing.get_origin(annotation) is typing.Literal:
            out[name] = typing.get_args(annotation)
        elif isinstance(annotation, type) and issubclass(annotation, Enum):
            out[name] = tuple(annotation)
    return out
