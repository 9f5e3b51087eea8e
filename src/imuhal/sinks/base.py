"""What a sink is: anything that takes the pipeline's events and is closed at the end."""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Mapping
from typing import Any, ClassVar, Protocol, runtime_checkable

from pydantic import BaseModel, ConfigDict

from imuhal.core.samples import Sample
from imuhal.estimation.outputs import Estimate

Event = Sample | Estimate
"""What a pipeline yields: body-frame samples (flagged ones included) and estimates."""


@runtime_checkable
class Sink(Protocol):
    """Receives every event of a run in time order; ``close`` is called once when the run
    ends or is stopped (a file sink commits its output there). When the run fails,
    ``Pipeline.run`` calls the sink's ``abort()`` instead if it has one (a file sink then keeps
    the previous file; :class:`~imuhal.sinks.builtin.CsvSink` keeps its rows beside it), else
    ``close``. A sink with a ``run_counts() -> dict[str, int]`` method has those counts in the
    run summary (read after closing)."""

    def handle(self, event: Event) -> None: ...

    def close(self) -> None: ...


class NoSettings(BaseModel):
    """Settings of a sink that takes none."""

    model_config = ConfigDict(extra="forbid", frozen=True)


class SinkPlugin(ABC):
    """Base of a sink a plugin registers (``imuhal_register_sinks``) so that users can pick
    it by name: ``imuhal run --sink NAME[:KEY=VALUE,...]``, or
    ``registry.sinks.get(NAME)(settings)`` from Python.

    ``Settings`` (a pydantic model) checks the ``KEY=VALUE`` options; units go in the names.
    """

    name: ClassVar[str] = ""
    description: ClassVar[str] = ""
    Settings: ClassVar[type[BaseModel]] = NoSettings

    def __init__(self, settings: BaseModel | Mapping[str, Any] | None = None) -> None:
        if not isinstance(settings, self.Settings):
            settings = self.Settings.model_validate(dict(settings or {}))
        self.settings = settings

    @abstractmethod
    def handle(self, event: Event) -> None:
        """Take one event (called in time order)."""

    @abstractmethod
    def close(self) -> None:
        """The run is over (also after a failure): flush, commit or discard."""
