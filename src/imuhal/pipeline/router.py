"""The routing rule: which estimator gets which sample, block or estimate, in which order.

One rule, used by the live pipeline (:class:`imuhal.pipeline.pipeline.Pipeline`) and by the
offline chain (:mod:`imuhal.offline.chain`: ``imuhal estimate`` over a run log, replays,
evaluations), so that an offline run over a recording's valid samples gives the live run's
estimates:

- samples of one instant (equal ``t_ns``) go to the estimators in fusion order
  (:mod:`imuhal.estimation.ordering`: accelerometer, magnetometer, pressure, temperature,
  then gyro; ties by device rank), whatever order the drivers emitted them in;
- each sample or estimate goes to every estimator that consumes its type and takes its
  source (``inputs``: device and estimator names, as a profile's estimator ``inputs``; an
  estimator without ``inputs`` takes every source), in profile order, except the estimator
  that made it;
- estimates are handed on breadth first, in the order they were made, before the next
  sample;
- a block of several frames (a FIFO read) goes whole to ``Estimator.update_block`` of each
  estimator it is routed to when nothing can come between its frames there: no other item
  of the same fusion step is routed to that estimator, it takes no other estimator's
  estimates, and nobody consumes its estimates. Otherwise its frames are routed one by
  one, in fusion order with the rest. Either way every estimator sees the same inputs in
  the same order; only the interleaving of different estimators' estimates in the output
  may differ (each estimator's own stay in order).
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from typing import Protocol

from imuhal.core.blocks import Block
from imuhal.core.samples import Sample
from imuhal.estimation.base import Estimator
from imuhal.estimation.ordering import fusion_order
from imuhal.estimation.outputs import Estimate

Item = Sample | Estimate


class Guard(Protocol):
    """Runs one estimator contained (the live pipeline's imuhal.pipeline.containment): its
    estimates for an item or a block, checked; [] when it failed or is disabled."""

    def process(self, item: Item) -> list[Estimate]: ...

    def process_block(self, block: Block) -> list[Estimate]: ...


@dataclass
class Route:
    """One estimator as the router sees it."""

    name: str
    """The estimator instance's name (a profile's estimator key)."""
    estimator: Estimator
    inputs: frozenset[str] | None
    """The sources it takes (device and estimator names); None: every source."""
    consumes: tuple[type, ...]
    outputs: int = 0
    """Estimates it has made so far."""
    guard: Guard | None = None
    """Calls the estimator contained (live runs); None: called directly (offline chain)."""


def source_of(item: Item) -> str:
    """The device of a sample, the estimator instance of an estimate."""
    return item.device if isinstance(item, Sample) else item.source


class Router:
    """Routes samples, blocks and estimates through ``routes`` (profile order) by the rule
    of the module docstring. ``device_rank``: the profile's device order, for samples of one
    instant and one quantity from two devices."""

    def __init__(self, routes: Sequence[Route],
                 device_rank: Mapping[str, int] | None = None) -> None:
        self.routes = tuple(routes)
        self.device_rank = dict(device_rank or {})
        self._cache: dict[tuple[str, type], tuple[Route, ...]] = {}
        consumed_sources: set[str] = set()
        for r in self.routes:
            if r.inputs is None:
                consumed_sources.update(x.name for x in self.routes if x is not r)
            else:
                consumed_sources.update(r.inputs)
        names = {r.name for r in self.routes}
        self._whole = frozenset(
            r.name for r in self.routes
            if r.name not in consumed_sources
            and not (any(issubclass(t, Estimate) for t in r.consumes)
                     and (r.inputs is None or names & r.inputs)))
        """Estimators whose estimates nobody takes and that take no other estimator's:
        nothing made during a fusion step can reach them, so a block may go whole."""

    @classmethod
    def of(cls, estimators: Sequence[Estimator],
           inputs: Mapping[str, Iterable[str]] | None = None,
           device_rank: Mapping[str, int] | None = None) -> Router:
        """A router over plain estimators: each named by its ``instance``, taking the
        sources ``inputs`` names for it (every source when not named)."""
        given = {name: frozenset(sources) for name, sources in (inputs or {}).items()}
        return cls([Route(est.instance, est, given.get(est.instance), tuple(est.consumes))
                    for est in estimators], device_rank)

    def routes_of(self, source: str, kind: type) -> tuple[Route, ...]:
        """The estimators an item of type ``kind`` from ``source`` goes to, in profile
        order (worked out once per source and type)."""
        key = (source, kind)
        routes = self._cache.get(key)
        if routes is None:
            routes = self._cache[key] = tuple(
                r for r in self.routes
                if (r.inputs is None or source in r.inputs) and source != r.name
                and issubclass(kind, r.consumes))
        return routes

    def takes(self, source: str, kind: type) -> bool:
        """True when some estimator takes items of ``kind`` from ``source``."""
        return bool(self.routes_of(source, kind))

    def route(self, item: Item, out: list[Estimate]) -> None:
        """``item`` through every estimator it is routed to, and their estimates through
        theirs, breadth first; every estimate is appended to ``out``."""
        cache = self._cache
        first = len(out)
        current = item
        while True:
            source = current.device if isinstance(current, Sample) else current.source
            routes = cache.get((source, type(current)))
            if routes is None:
                routes = self.routes_of(source, type(current))
            for r in routes:
                guard = r.guard
                made = guard.process(current) if guard is not None else \
                    r.estimator.process(current)
                if made:
                    if type(made) is not list:  # any iterable a plugin returns
                        made = list(made)
                    r.outputs += len(made)
                    out.extend(made)
            if first == len(out):
                return
            current = out[first]
            first += 1

    def fuse(self, samples: list[Sample], out: list[Estimate]) -> None:
        """``samples`` (valid, due) in fusion order through :meth:`route`."""
        route = self.route
        for s in (samples if len(samples) == 1 else fusion_order(samples, self.device_rank)):
            route(s, out)

    def fuse_blocks(self, blocks: Sequence[Block], out: list[Estimate]) -> None:
        """The frames of ``blocks`` (valid, due: one fusion step) through the estimators:
        blocks that may go whole to ``update_block`` do so (see the module docstring), the
        rest frame by frame in fusion order."""
        whole: list[tuple[Block, tuple[Route, ...]]] = []
        rows: list[Sample] = []
        for block in blocks:
            routes = self.routes_of(block.device, block.kind)
            if len(block) > 1 and routes and self._alone(block, routes, blocks):
                whole.append((block, routes))
            else:
                rows += block.samples()
        for block, routes in whole:
            for r in routes:
                made = r.guard.process_block(block) if r.guard is not None else \
                    list(r.estimator.update_block(block))
                r.outputs += len(made)
                out.extend(made)
        if rows:
            self.fuse(rows, out)

    def _alone(self, block: Block, routes: tuple[Route, ...], blocks: Sequence[Block]
               ) -> bool:
        """Nothing else of this step reaches ``block``'s estimators, and their estimates go
        nowhere: its frames may be handed over at once."""
        if any(r.name not in self._whole for r in routes):
            return False
        names = {r.name for r in routes}
        return not any(other is not block and names.intersection(
            r.name for r in self.routes_of(other.device, other.kind)) for other in blocks)
