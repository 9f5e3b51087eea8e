"""What a sink is: anything that takes the pipeline's events and is closed at the end."""

from __future__ import annotations

from typing import Protocol, runtime_checkable

from imuhal.core.samples import Sample
from imuhal.estimation.outputs import Estimate

Event = Sample | Estimate
"""What a pipeline yields: body-frame samples (flagged ones included) and estimates."""


@runtime_checkable
class Sink(Protocol):
    """Receives every event of a run in time order; ``close`` is called once, also when the
    run fails (a file sink commits or discards its output there)."""

    def handle(self, event: Event) -> None: ...

    def close(self) -> None: ...
