"""Bus kinds as plugins: a factory turns a profile's bus settings into an open Bus."""

from __future__ import annotations

from abc import ABC, abstractmethod
from typing import ClassVar

from pydantic import BaseModel, ConfigDict

from imuhal.bus.base import Bus, BusKind


class BusSettings(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


class BusFactory(ABC):
    """Opens buses of one kind. ``scheme`` is the ``kind:`` a profile writes."""

    scheme: ClassVar[str]
    kind: ClassVar[BusKind]
    Settings: ClassVar[type[BusSettings]]
    description: ClassVar[str] = ""

    @classmethod
    @abstractmethod
    def open(cls, name: str, settings: BusSettings) -> Bus:
        """Open the OS resource; raise BusError with the path and a hint if it cannot."""
