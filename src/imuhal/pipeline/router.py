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
- the blocks of a fusion step with several frames (a FIFO read) go stage by stage when
  that changes no estimator's inputs: each estimator fed by the step's blocks gets all of
  its blocks at once (``Estimator.update_blocks``: its frames in fusion order) and takes
  no estimates of another estimator reached in this step; each estimator reached by
  estimates only takes them from one estimator of the step, and gets them in the order
  they were made, after that estimator's stage. Otherwise (an estimator fed by both the
  step's samples and another's estimates, or by two estimators) every frame is routed one
  by one in fusion order with the rest. Either way every estimator sees the same inputs in
  the same order; only the interleaving of different estimators' estimates in the output
  may differ (each estimator's own stay in order). A stage's estimates may stay columns
  (``fuse_blocks(..., estimate_blocks=True)``, the live pipeline: an AHRS's
  :class:`~imuhal.estimation.outputs.AttitudeBlock`), handed whole to the estimators they
  reach; its rows are the estimates the frames one by one would have made.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any, Protocol

from imuhal.core.blocks import Block
from imuhal.core.samples import Sample
from imuhal.estimation.base import Estimator
from imuhal.estimation.ordering import FUSION_RANK, fusion_order
from imuhal.estimation.outputs import AttitudeBlock, AttitudeEstimate, Estimate

Item = Sample | Estimate


class Guard(Protocol):
    """Runs one estimator contained (the live pipeline's imuhal.pipeline.containment): its
    estimates for an item or a block, checked; [] when it failed or is disabled."""

    def process(self, item: Item) -> list[Estimate]: ...

    def process_block(self, block: Block) -> list[Estimate]: ...

    def process_blocks(self, blocks: Sequence[Block]) -> list[Estimate]: ...

    def estimate_blocks(self, blocks: Sequence[Block]) -> list[Estimate | AttitudeBlock]: ...

    def process_estimate_block(self, block: AttitudeBlock) -> list[Estimate]: ...


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
        self._plans: dict[tuple[tuple[str, type], ...], _Plan | None] = {}

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
        routes = self._cache.get((source, kind))  # asked for every reading: no call then
        return bool(routes if routes is not None else self.routes_of(source, kind))

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

    def fuse_blocks(self, blocks: Sequence[Block], out: list[Estimate], *,
                    estimate_blocks: bool = False) -> None:
        """The frames of ``blocks`` (valid, due: one fusion step) through the estimators:
        stage by stage where that changes no estimator's inputs (see the module
        docstring), else frame by frame in fusion order. ``estimate_blocks``: a stage's
        estimates may stay blocks (``Estimator.estimate_blocks``: AttitudeBlocks, whose
        rows are its estimates), handed whole to the estimators they reach
        (``Estimator.update_estimate_block``) and appended to ``out`` as blocks."""
        plan = None
        if any(len(b) > 1 for b in blocks):
            key = tuple((b.device, b.kind) for b in blocks)
            if key in self._plans:
                plan = self._plans[key]
            else:
                plan = self._plans[key] = self._plan(blocks)
        if plan is None:
            self.fuse([s for b in blocks for s in b.samples()], out)
            return
        made: dict[str, list[Estimate | AttitudeBlock]] = {}
        for r, which in plan.fed:
            self._made(r, _fed(r, [blocks[i] for i in which], estimate_blocks), made, out)
        for r, upstream in plan.downstream:
            self._made(r, self._downstream(r, upstream, made[upstream]), made, out)

    def _downstream(self, r: Route, upstream: str, made: list[Estimate | AttitudeBlock]
                    ) -> list[Estimate | AttitudeBlock]:
        """What ``r`` makes of the estimates ``upstream`` made in this step (those routed
        to it), in the order they were made; an AttitudeBlock whole."""
        got: list[Estimate | AttitudeBlock] = []
        guard = r.guard
        for e in made:
            if isinstance(e, AttitudeBlock):
                if any(x is r for x in self.routes_of(upstream, AttitudeEstimate)):
                    got += guard.process_estimate_block(e) if guard is not None else \
                        r.estimator.update_estimate_block(e)
            elif any(x is r for x in self.routes_of(upstream, type(e))):
                got += guard.process(e) if guard is not None else r.estimator.process(e)
        return got

    @staticmethod
    def _made(r: Route, got: list[Estimate | AttitudeBlock],
              made: dict[str, list[Estimate | AttitudeBlock]], out: list[Any]) -> None:
        r.outputs += sum(len(e) if type(e) is AttitudeBlock else 1 for e in got)
        out.extend(got)
        made[r.name] = got

    def _plan(self, blocks: Sequence[Block]) -> _Plan | None:
        """How the blocks of one fusion step go stage by stage, or None: frame by frame
        (see the module docstring)."""
        fed: dict[str, list[int]] = {}
        for i, b in enumerate(blocks):
            for r in self.routes_of(b.device, b.kind):
                fed.setdefault(r.name, []).append(i)
        for which in fed.values():
            ranks = [FUSION_RANK.get(blocks[i].quantity, 2) for i in which]
            if len(set(ranks)) != len(ranks):
                return None  # frames of one instant and rank: their order is the device's
        stage = [r for r in self.routes if r.name in fed]
        upstream: dict[str, str] = {}
        reached: list[Route] = []
        queue = list(stage)
        for u in queue:  # grows while iterating: breadth first
            for d in self.routes:
                if d is u or not _takes_estimates_of(d, u):
                    continue
                if d.name in fed or upstream.get(d.name, u.name) != u.name:
                    return None  # its inputs would interleave: frame by frame
                if d.name not in upstream:
                    upstream[d.name] = u.name
                    reached.append(d)
                    queue.append(d)
        return _Plan(tuple((r, tuple(fed[r.name])) for r in stage),
                     tuple((r, upstream[r.name]) for r in reached))


def _fed(r: Route, blocks: list[Block], estimate_blocks: bool
         ) -> list[Estimate | AttitudeBlock]:
    """What ``r`` makes of its blocks of one fusion step (``estimate_blocks``: as
    ``Estimator.estimate_blocks`` makes it, else ``update_blocks``)."""
    guard = r.guard
    if estimate_blocks:
        return guard.estimate_blocks(blocks) if guard is not None else \
            r.estimator.estimate_blocks(blocks)
    return list(guard.process_blocks(blocks) if guard is not None else
                r.estimator.update_blocks(blocks))


def _takes_estimates_of(d: Route, u: Route) -> bool:
    """``d`` may take estimates made by ``u`` (it consumes some estimate and takes ``u`` as
    a source)."""
    return (d.inputs is None or u.name in d.inputs) and any(
        issubclass(t, Estimate) for t in d.consumes)


@dataclass(frozen=True)
class _Plan:
    """One fusion step stage by stage: the estimators fed by its blocks (with the positions
    of their blocks), then those reached by estimates, each with its one upstream."""

    fed: tuple[tuple[Route, tuple[int, ...]], ...]
    downstream: tuple[tuple[Route, str], ...]
