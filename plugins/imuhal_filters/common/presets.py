"""Named presets for estimator settings: accurate defaults, reference values on request.

An estimator's defaults are the values measured to be the most accurate for flight and
hand-held use (each documented in docs/estimators.md with the measurement that chose it).
The values of the reference implementation or of the seed firmware stay one word away:
``preset: reference`` (what the conformance tests run) or ``preset: seed``. A preset only
fills the settings the user did not give, so ``{preset: seed, beta: 0.2}`` is the seed's
filter with another gain.
"""

from __future__ import annotations

from typing import Any, ClassVar

from pydantic import model_validator

from imuhal.estimation.base import EstimatorSettings

DEFAULT_PRESET = "default"


class PresetSettings(EstimatorSettings):
    """Settings with named presets. Subclasses fill ``PRESETS`` (name -> field values)."""

    PRESETS: ClassVar[dict[str, dict[str, Any]]] = {}

    preset: str = DEFAULT_PRESET
    """``default`` (the accurate choice) or one of the estimator's named presets."""

    @model_validator(mode="before")
    @classmethod
    def _apply_preset(cls, data: Any) -> Any:
        if not isinstance(data, dict):
            return data
        name = data.get("preset", DEFAULT_PRESET)
        if name == DEFAULT_PRESET:
            return data
        if not isinstance(name, str) or name not in cls.PRESETS:
            known = ", ".join([DEFAULT_PRESET, *cls.PRESETS])
            raise ValueError(f"unknown preset {name!r}; presets: {known}")
        return {**cls.PRESETS[name], **data}
