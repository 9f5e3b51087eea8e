"""Chaining estimators offline as the pipeline does: samples in, every estimate out.

A profile may run estimators behind one another (an AHRS whose attitude estimates feed a
vario filter's gravity compensation). Offline, over recorded samples, the same chain must
see the same inputs in the same order as live, or its estimates differ from the run's:

- samples of one instant (equal ``t_ns``) go to the estimators in fusion order
  (:mod:`imuhal.estimation.ordering`: accelerometer, magnetometer, pressure, temperature,
  then gyro), whatever order the drivers emitted them in;
- each sample or estimate goes to every estimator that consumes its type and takes its
  source (``inputs``: device and estimator names, as a profile's estimator ``inputs``; an
  estimator not named there takes every source), in the order the estimators are given
  (the profile's), except the estimator that made it;
- estimates are handed on breadth first, in the order they were made, before the next
  sample.

That is the pipeline's rule (imuhal.pipeline.pipeline: ``_fuse``, ``_estimate``). A
recording's valid samples, fed through :func:`run_chain` with freshly built estimators and
the profile's ``inputs``, give the live run's estimates (tests/offline/test_chain.py).
"""

from __future__ import annotations

from collections.abc import Collection, Iterable, Iterator, Mapping, Sequence

from imuhal.core.samples import Sample
from imuhal.estimation.base import Estimator
from imuhal.estimation.ordering import FUSION_RANK
from imuhal.estimation.outputs import Estimate


class EstimatorChain:
    """Estimators in profile order; :meth:`process` routes one item through all of them.
    ``inputs``: per estimator instance, the sources (device or estimator instance names) it
    takes, as the profile's ``inputs``; one not named takes every source."""

    def __init__(self, estimators: Sequence[Estimator],
                 inputs: Mapping[str, Collection[str]] | None = None) -> None:
        self.estimators = tuple(estimators)
        self.inputs = {name: frozenset(sources) for name, sources in (inputs or {}).items()}
        self._routes: dict[tuple[str, type], tuple[Estimator, ...]] = {}

    def _routes_of(self, source: str, kind: type) -> tuple[Estimator, ...]:
        routes = self._routes[(source, kind)] = tuple(
            est for est in self.estimators
            if issubclass(kind, tuple(est.consumes)) and est.instance != source
            and source in self.inputs.get(est.instance, (source,)))
        return routes

    def process(self, item: Sample | Estimate, out: list[Estimate] | None = None
                ) -> list[Estimate]:
        """Every estimate ``item`` leads to, in the order made (``item``'s consumers first,
        then the consumers of their estimates, breadth first), appended to ``out`` (a new
        list by default) and returned."""
        if out is None:
            out = []
        routes_of = self._routes
        handed_on = len(out)
        current: Sample | Estimate = item
        while True:
            source = current.source if isinstance(current, Estimate) else current.device
            routes = routes_of.get((source, type(current)))
            if routes is None:
                routes = self._routes_of(source, type(current))
            for est in routes:
                out += est.process(current)
            if handed_on == len(out):
                return out
            current = out[handed_on]
            handed_on += 1


def instants_in_fusion_order(samples: Iterable[Sample]) -> Iterator[Sample]:
    """``samples`` (a recording, in the order the pipeline emitted them) with each run of
    consecutive samples of one instant (equal ``t_ns``) put in fusion order; the order of
    different instants is kept (a late GNSS fix stays where it arrived)."""
    instant: list[Sample] = []
    for s in samples:
        if instant and s.t_ns != instant[0].t_ns:
            yield from _ranked(instant)
            instant = []
        instant.append(s)
    yield from _ranked(instant)


def _ranked(instant: list[Sample]) -> list[Sample]:
    if len(instant) < 2:
        return instant
    # stable: samples of one quantity keep their (device, poll) order
    return sorted(instant, key=lambda s: FUSION_RANK.get(s.channel, 2))


def run_chain(estimators: Sequence[Estimator], samples: Iterable[Sample], *,
              inputs: Mapping[str, Collection[str]] | None = None) -> list[Estimate]:
    """Every estimate the chain of ``estimators`` (profile order; ``inputs`` as for
    :class:`EstimatorChain`) makes from ``samples`` (valid samples as the pipeline emitted
    them, e.g. collected from ``Pipeline.events``), in the order made. One estimator's are
    those with ``e.source == est.instance``."""
    chain = EstimatorChain(estimators, inputs)
    out: list[Estimate] = []
    process = chain.process
    for s in instants_in_fusion_order(samples):
        process(s, out)
    return out
