"""The routing rule (imuhal.pipeline.router): a fusion step's blocks go stage by stage
(``update_blocks``, then the estimates downstream) only where that changes no estimator's
inputs, and every estimator sees the same inputs in the same order either way."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any, ClassVar

import numpy as np

from imuhal.core.blocks import Block
from imuhal.core.samples import AccelSample, Frame, GyroSample, MagSample, Sample
from imuhal.estimation.base import Estimator, EstimatorSettings
from imuhal.estimation.ordering import blocks_in_fusion_order, fusion_order
from imuhal.estimation.outputs import Estimate, VerticalEstimate
from imuhal.offline.chain import EstimatorChain
from imuhal.pipeline.router import Router


class _Summing(Estimator):
    """Emits the running sum of the x components it was fed, one estimate per input."""

    name: ClassVar[str] = "summing"
    Settings: ClassVar[type[EstimatorSettings]] = EstimatorSettings
    consumes: ClassVar[tuple[type, ...]] = (GyroSample, AccelSample)

    def reset(self) -> None:
        self.total = 0.0
        self.blocks_taken = 0
        self.inputs: list[tuple[str, int, float]] = []

    def process(self, item: Sample | Estimate) -> list[Estimate]:
        self.inputs.append((type(item).__name__, item.t_ns, getattr(item, "climb_m_s", 0.0)))
        if not isinstance(item, GyroSample | AccelSample):
            return []
        self.total = self.total * 0.5 + item.vector[0]
        return [VerticalEstimate(t_ns=item.t_ns, source=self.instance,
                                 altitude_m=0.0, climb_m_s=self.total)]

    def update_blocks(self, blocks: Sequence[Block]) -> list[Estimate]:
        self.blocks_taken += 1
        return super().update_blocks(blocks)

    def get_state(self) -> dict[str, Any]:
        return {"total": self.total}

    def set_state(self, state: dict[str, Any]) -> None:
        self.total = state["total"]


def _block(kind: type[GyroSample] | type[AccelSample], device: str, n: int,
           offset: float) -> Block:
    values = np.column_stack([np.arange(n) + offset, np.zeros(n), np.zeros(n)])
    return Block.regular(kind, device, 1_000, 1_000_000, values, frame=Frame.BODY_NED)


def _climbs(out: list[Estimate]) -> list[tuple[int, float]]:
    return [(e.t_ns, e.climb_m_s) for e in out]  # type: ignore[attr-defined]


def test_the_default_update_block_is_process_frame_by_frame() -> None:
    block = _block(GyroSample, "imu", 6, 0.25)
    by_block, by_frame = _Summing(), _Summing()
    frames: list[Estimate] = []
    for s in block.samples():
        frames += by_frame.process(s)
    assert _climbs(by_block.update_block(block)) == _climbs(frames)


def test_a_block_alone_at_a_leaf_estimator_goes_whole() -> None:
    est = _Summing()
    out: list[Estimate] = []
    Router.of([est]).fuse_blocks([_block(GyroSample, "imu", 10, 0.0)], out)
    assert est.blocks_taken == 1
    assert len(out) == 10


def test_blocks_that_meet_at_one_estimator_reach_it_together_in_fusion_order() -> None:
    est, reference = _Summing(), _Summing()
    gyro, accel = _block(GyroSample, "imu", 5, 100.0), _block(AccelSample, "imu", 5, 1.0)
    out: list[Estimate] = []
    Router.of([est]).fuse_blocks([gyro, accel], out)
    assert est.blocks_taken == 1
    expected: list[Estimate] = []
    for a, g in zip(accel.samples(), gyro.samples(), strict=True):  # accel before gyro
        expected += reference.process(a) + reference.process(g)
    assert _climbs(out) == _climbs(expected)


class _Follower(_Summing):
    """Takes another estimator's estimates (and, when routed, samples)."""

    name: ClassVar[str] = "follower"
    consumes: ClassVar[tuple[type, ...]] = (GyroSample, VerticalEstimate)


def _frame_by_frame(router: Router, blocks: list[Block]) -> list[Estimate]:
    out: list[Estimate] = []
    router.fuse([s for b in blocks for s in b.samples()], out)
    return out


def test_a_chain_goes_stage_by_stage_and_each_estimator_sees_its_inputs_in_order() -> None:
    first, follower = _Summing(instance="first"), _Follower(instance="follower")
    ref_first, ref_follower = _Summing(instance="first"), _Follower(instance="follower")
    inputs = {"follower": ["first"]}
    blocks = [_block(GyroSample, "imu", 4, 0.0), _block(AccelSample, "imu", 4, 2.0)]
    out: list[Estimate] = []
    Router.of([first, follower], inputs).fuse_blocks(blocks, out)
    ref = _frame_by_frame(Router.of([ref_first, ref_follower], inputs), blocks)
    assert first.blocks_taken == 1
    assert follower.inputs == ref_follower.inputs and len(follower.inputs) == 8
    for source in ("first", "follower"):
        assert [e for e in out if e.source == source] == \
            [e for e in ref if e.source == source]


def test_an_estimator_fed_by_samples_and_by_another_estimator_takes_frames_one_by_one(
        ) -> None:
    upstream, listener = _Summing(instance="upstream"), _Follower(instance="listener")
    ref_listener = _Follower(instance="listener")
    inputs = {"listener": ["imu", "upstream"]}
    blocks = [_block(GyroSample, "imu", 4, 0.0)]
    out: list[Estimate] = []
    Router.of([upstream, listener], inputs).fuse_blocks(blocks, out)
    ref = _frame_by_frame(Router.of([_Summing(instance="upstream"), ref_listener], inputs),
                          blocks)
    assert upstream.blocks_taken == 0 and listener.blocks_taken == 0
    assert listener.inputs == ref_listener.inputs  # sample, estimate, sample, ...
    assert _climbs(out) == _climbs(ref)


def test_an_estimator_fed_by_two_estimators_of_one_step_takes_frames_one_by_one() -> None:
    a, b = _Summing(instance="a"), _Summing(instance="b")
    both = _Follower(instance="both")
    router = Router.of([a, b, both], {"a": ["imu"], "b": ["acc"], "both": ["a", "b"]})
    out: list[Estimate] = []
    router.fuse_blocks([_block(GyroSample, "imu", 3, 0.0), _block(AccelSample, "acc", 3, 1.0)],
                       out)
    assert a.blocks_taken == 0 and b.blocks_taken == 0
    assert [i[1] for i in both.inputs] == sorted(i[1] for i in both.inputs)  # by frame


def test_the_offline_chain_routes_by_the_pipelines_rule() -> None:
    """``inputs`` name the sources an estimator takes; one not named takes every source."""
    only_imu, every = _Summing(instance="only_imu"), _Summing(instance="every")
    chain = EstimatorChain([only_imu, every], {"only_imu": ["imu"]})
    assert isinstance(chain.router, Router)
    other = _block(GyroSample, "other", 1, 3.0).samples()[0]
    made = chain.process(other)
    assert [e.source for e in made] == ["every"]


def test_the_frames_of_blocks_come_in_fusion_order_ties_in_block_order() -> None:
    """``blocks_in_fusion_order`` (the default ``update_blocks``'s order) is ``fusion_order``
    of the blocks' frames, on awkward times: shared instants, a stamp repeated in one block,
    blocks given gyro first, a block with no frame at another's instant."""
    rng = np.random.default_rng(7)
    for _ in range(50):
        blocks = []
        for kind in (GyroSample, AccelSample, MagSample):
            t = np.sort(rng.choice([1_000, 2_000, 3_000, 4_000], size=int(rng.integers(1, 6))))
            values = rng.normal(size=(len(t), 3))
            blocks.append(Block.from_arrays(kind, "imu", int(t[0]), t - t[0], values,
                                            np.zeros(len(t), np.int64), frame=Frame.BODY_NED))
        frames = [s for b in blocks for s in b.samples()]
        assert blocks_in_fusion_order(blocks) == fusion_order(frames)
