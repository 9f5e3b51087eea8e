"""``--set key=value`` arguments into an estimator's own pydantic settings."""

from __future__ import annotations

from typing import Any, TypeVar

import yaml
from pydantic import BaseModel, ValidationError

from imuhal.core.errors import ImuhalError
from imuhal.profile.loader import validate_strict

ModelT = TypeVar("ModelT", bound=BaseModel)


class SettingsArgumentError(ImuhalError):
    pass


def parse_set_arguments(items: list[str], flag: str = "--set") -> dict[str, Any]:
    """``["beta=0.1", "accel_gate_g=0.6,1.4"]`` -> ``{"beta": 0.1, "accel_gate_g": [0.6, 1.4]}``.

    Values are YAML scalars (numbers, true/false, null, strings); commas make a list.
    """
    out: dict[str, Any] = {}
    for item in items:
        key, sep, raw = item.partition("=")
        key = key.strip()
        if not sep or not key:
            raise SettingsArgumentError(f"{flag} {item!r}: write KEY=VALUE, e.g. {flag} beta=0.1")
        if key in out:
            raise SettingsArgumentError(f"{_named(flag, key)}: given twice")
        parts = [_scalar(p) for p in raw.split(",")] if "," in raw else _scalar(raw)
        out[key] = parts
    return out


def _scalar(text: str) -> Any:
    try:
        return yaml.safe_load(text.strip()) if text.strip() else ""
    except yaml.YAMLError:
        return text.strip()


def build_settings(model: type[ModelT], values: dict[str, Any], owner: str,
                   flag: str = "--set") -> ModelT:
    """Validate ``values`` with ``model``; every problem names its ``flag`` key and the
    allowed."""
    try:
        return validate_strict(model, values)
    except ValidationError as exc:
        problems = []
        for err in exc.errors(include_url=False):
            key = ".".join(str(p) for p in err["loc"]) or "(settings)"
            if err["type"] == "extra_forbidden":
                allowed = ", ".join(model.model_fields)
                problems.append(f"{_named(flag, key)}: {owner} has no such setting; "
                                f"settings: {allowed or 'none'}")
            else:
                msg = err["msg"]
                if isinstance(err.get("ctx"), dict) and "error" in err["ctx"]:
                    msg = str(err["ctx"]["error"])  # a validator's own words, no pydantic prefix
                problems.append(f"{_named(flag, key)}: {msg} (found {err.get('input')!r})")
        raise SettingsArgumentError("; ".join(problems)) from None


def _named(flag: str, key: str) -> str:
    """How the user wrote the setting: ``--set beta``, or ``--sink-set log.path`` for a flag
    that takes ``NAME.KEY`` (given as ``--sink-set log.``)."""
    return f"{flag}{key}" if flag.endswith(".") else f"{flag} {key}"
