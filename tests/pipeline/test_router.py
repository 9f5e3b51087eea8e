"""The routing rule (imuhal.pipeline.router): blocks go whole to ``update_block`` only where
nothing can come between their frames, and every estimator sees the same inputs either way."""

from __future__ import annotations

from typing import Any, ClassVar

import numpy as np

from imuhal.core.blocks import Block
from imuhal.core.samples import AccelSample, Frame, GyroSample, Sample
from imuhal.estimation.base import Estimator, EstimatorSettings
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

    def process(self, item: Sample | Estimate) -> list[Estimate]:
        assert isinstance(item, GyroSample | AccelSample)
        self.total = self.total * 0.5 + item.vector[0]
        return [VerticalEstimate(t_ns=item.t_ns, source=self.instance,
                                 altitude_m=0.0, climb_m_s=self.total)]

    def update_block(self, block: Block) -> list[Estimate]:
        self.blocks_taken += 1
        return super().update_block(block)

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


def test_blocks_that_meet_at_one_estimator_are_fused_frame_by_frame_in_fusion_order() -> None:
    est, reference = _Summing(), _Summing()
    gyro, accel = _block(GyroSample, "imu", 5, 100.0), _block(AccelSample, "imu", 5, 1.0)
    out: list[Estimate] = []
    Router.of([est]).fuse_blocks([gyro, accel], out)
    assert est.blocks_taken == 0
    expected: list[Estimate] = []
    for a, g in zip(accel.samples(), gyro.samples(), strict=True):  # accel before gyro
        expected += reference.process(a) + reference.process(g)
    assert _climbs(out) == _climbs(expected)


def test_an_estimator_whose_estimates_feed_another_never_takes_a_block_whole() -> None:
    class _Follower(_Summing):
        name: ClassVar[str] = "follower"
        consumes: ClassVar[tuple[type, ...]] = (VerticalEstimate,)

        def process(self, item: Sample | Estimate) -> list[Estimate]:
            return []

    first = _Summing(instance="first")
    out: list[Estimate] = []
    Router.of([first, _Follower()]).fuse_blocks([_block(GyroSample, "imu", 4, 0.0)], out)
    assert first.blocks_taken == 0 and len(out) == 4


def test_an_estimator_fed_by_another_estimator_never_takes_a_block_whole() -> None:
    class _Listener(_Summing):
        name: ClassVar[str] = "listener"
        consumes: ClassVar[tuple[type, ...]] = (GyroSample, VerticalEstimate)

        def process(self, item: Sample | Estimate) -> list[Estimate]:
            return super().process(item) if isinstance(item, GyroSample) else []

    upstream, listener = _Summing(instance="upstream"), _Listener(instance="listener")
    router = Router.of([upstream, listener], {"upstream": ["acc"], "listener": ["imu",
                                                                              "upstream"]})
    out: list[Estimate] = []
    router.fuse_blocks([_block(GyroSample, "imu", 4, 0.0)], out)
    assert listener.blocks_taken == 0 and len(out) == 4


def test_the_offline_chain_routes_by_the_pipelines_rule() -> None:
    """``inputs`` name the sources an estimator takes; one not named takes every source."""
    only_imu, every = _Summing(instance="only_imu"), _Summing(instance="every")
    chain = EstimatorChain([only_imu, every], {"only_imu": ["imu"]})
    assert isinstance(chain.router, Router)
    other = _block(GyroSample, "other", 1, 3.0).samples()[0]
    made = chain.process(other)
    assert [e.source for e in made] == ["every"]
