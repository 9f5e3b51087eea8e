"""Chaining estimators offline as the pipeline does: samples in, every estimate out.

A profile may run estimators behind one another (an AHRS whose attitude estimates feed a
vario filter's gravity compensation). Offline, over recorded samples, the same chain must
see the same inputs in the same order as live, or its estimates differ from the run's. It
does, because it routes through the pipeline's own router (imuhal.pipeline.router: fusion
order within an instant, profile order between estimators, estimates handed on breadth
first). A recording's valid samples, fed through :func:`run_chain` with freshly built
estimators and the profile's ``inputs``, give the live run's estimates
(tests/offline/test_chain.py).

Estimates are checked as live (imuhal.estimation.outputs.estimate_flags): one that is not
finite or not normalisable is replaced by a RejectedEstimate before any other estimator of
the chain or the output sees it, and counted per estimator instance (``rejected``). An
estimator's exception still ends an offline run: there is no run to keep going.
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Collection, Iterable, Iterator, Mapping, Sequence
from typing import Any

from imuhal.core.blocks import Block
from imuhal.core.samples import Sample
from imuhal.estimation.base import Estimator
from imuhal.estimation.ordering import FUSION_RANK
from imuhal.estimation.outputs import (
    AttitudeBlock,
    Estimate,
    checked_estimates,
    usable_blocks_kept,
)
from imuhal.pipeline.router import Router


class _Checked:
    """Calls one estimator and checks its estimates (the router's Guard, offline)."""

    __slots__ = ("estimator", "rejected")

    def __init__(self, estimator: Estimator, rejected: Counter[str]) -> None:
        self.estimator = estimator
        self.rejected = rejected

    def _checked(self, made: Iterable[Any]) -> list[Any]:
        """``made`` with every estimate the check refuses replaced (AttitudeBlocks whose
        every row passes stay whole)."""
        out = made if type(made) is list else list(made or ())
        if out:
            replaced = checked_estimates(out, type(self.estimator).name)
            if replaced:
                self.rejected[self.estimator.instance] += replaced
        return out

    def process(self, item: Sample | Estimate) -> list[Estimate]:
        return self._checked(self.estimator.process(item))

    def process_block(self, block: Block) -> list[Estimate]:
        return self._checked(self.estimator.update_block(block))

    def process_blocks(self, blocks: Sequence[Block]) -> list[Estimate]:
        return self._checked(self.estimator.update_blocks(blocks))

    def estimate_blocks(self, blocks: Sequence[Block]) -> list[Estimate | AttitudeBlock]:
        return self._checked(usable_blocks_kept(self.estimator.estimate_blocks(blocks)))

    def process_estimate_block(self, block: AttitudeBlock) -> list[Estimate]:
        return self._checked(self.estimator.update_estimate_block(block))


class EstimatorChain:
    """Estimators in profile order; :meth:`process` routes one item through all of them
    (the pipeline's :class:`~imuhal.pipeline.router.Router`). ``inputs``: per estimator
    instance, the sources (device or estimator instance names) it takes, as the profile's
    ``inputs``; one not named takes every source."""

    def __init__(self, estimators: Sequence[Estimator],
                 inputs: Mapping[str, Collection[str]] | None = None) -> None:
        self.estimators = tuple(estimators)
        self.router = Router.of(self.estimators, inputs)
        self.rejected: Counter[str] = Counter()
        """Estimates refused (not finite, not normalisable), per estimator instance."""
        for route in self.router.routes:
            route.guard = _Checked(route.estimator, self.rejected)

    def process(self, item: Sample | Estimate, out: list[Estimate] | None = None
                ) -> list[Estimate]:
        """Every estimate ``item`` leads to, in the order made (``item``'s consumers first,
        then the consumers of their estimates, breadth first), appended to ``out`` (a new
        list by default) and returned."""
        if out is None:
            out = []
        self.router.route(item, out)
        return out


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
