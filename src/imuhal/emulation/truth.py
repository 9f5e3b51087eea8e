"""A sink that records an emulated run's ground truth next to its estimates."""

from __future__ import annotations

import os
from pathlib import Path

from imuhal.core.samples import Sample
from imuhal.sim.scenario import Scenario
from imuhal.sim.truth_csv import record_truth
from imuhal.sinks.base import Event


class TruthSink:
    """Records the simulated ground truth at the timestamps of the run's estimates (all
    events with ``include_samples``), written atomically as the documented truth CSV
    (docs/simulation.md) when the run closes, for computing any estimator's error."""

    def __init__(self, path: str | os.PathLike[str], scenario: Scenario, *,
                 include_samples: bool = False) -> None:
        self.path = Path(path)
        self.scenario = scenario
        self.include_samples = include_samples
        self._times_ns: list[int] = []

    def handle(self, event: Event) -> None:
        if isinstance(event, Sample) and not self.include_samples:
            return
        if not self._times_ns or self._times_ns[-1] != event.t_ns:
            self._times_ns.append(event.t_ns)

    @property
    def rows(self) -> int:
        return len(self._times_ns)

    def close(self) -> None:
        record_truth(self.path, self.scenario, (t / 1e9 for t in self._times_ns))

    def abort(self) -> None:
        """A failed run: write nothing, ``path`` keeps what it had."""
        self._times_ns.clear()
