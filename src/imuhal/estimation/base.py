"""What every estimator provides.

An estimator consumes samples (body frame, project units) and other estimators' outputs, and
produces Estimates. Its settings are a pydantic model kept apart from its state; its state
can be saved and restored. It knows nothing about buses or chips.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from typing import Any, ClassVar

from pydantic import BaseModel, ConfigDict

from imuhal.core.samples import Sample
from imuhal.estimation.outputs import Estimate


class EstimatorSettings(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


class Estimator(ABC):
    """Base of every estimator plugin.

    ``consumes`` lists the sample and estimate types the pipeline should hand to ``process``.
    """

    name: ClassVar[str]
    description: ClassVar[str] = ""
    Settings: ClassVar[type[EstimatorSettings]]
    consumes: ClassVar[tuple[type, ...]]

    def __init__(self, settings: EstimatorSettings | dict[str, Any] | None = None,
                 *, instance: str | None = None) -> None:
        if settings is None:
            settings = self.Settings()
        elif not isinstance(settings, self.Settings):
            settings = self.Settings.model_validate(settings)
        self.settings = settings
        self.instance = instance or self.name
        self.reset()

    @abstractmethod
    def reset(self) -> None:
        """Return to the initial state."""

    @abstractmethod
    def process(self, item: Sample | Estimate) -> list[Estimate]:
        """Consume one body-frame sample or upstream estimate; return new estimates."""

    @abstractmethod
    def get_state(self) -> dict[str, Any]:
        """A JSON-serialisable snapshot of the state (not the settings)."""

    @abstractmethod
    def set_state(self, state: dict[str, Any]) -> None:
        """Restore a snapshot taken by get_state."""

    def diagnostics(self) -> dict[str, Any]:
        return {}
