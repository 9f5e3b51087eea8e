"""Blocks of several frames through the pipeline: the GY-91 with its MPU-9250 read from the
FIFO (``read: fifo``), whose every read makes blocks of the frames it held."""

from __future__ import annotations

from collections.abc import Sequence
from itertools import pairwise

import pytest
from tests.support.chain import offline_estimates
from tests.support.fifo_boards import imu_read_from_fifo

from imuhal.core.blocks import Block
from imuhal.core.samples import AccelSample, Frame, GyroSample, Sample
from imuhal.drivers.base import BlockPoll
from imuhal.emulation import open_emulated
from imuhal.estimation.outputs import (
    AttitudeBlock,
    AttitudeEstimate,
    Estimate,
    VerticalEstimate,
)
from imuhal.pipeline.pipeline import Pipeline
from imuhal.pipeline.router import Router
from imuhal.plugins.manager import Registry, load_registry
from imuhal.profile.model import BoardProfile
from imuhal_chips.mpu9250.driver import MPU9250Driver

FIFO_FRAMES = 8
PERIOD_NS = 5_000_000  # the gy91's 200 Hz


@pytest.fixture(scope="module")
def registry() -> Registry:
    return load_registry()


def _gy91_fifo(registry: Registry) -> BoardProfile:
    """The GY-91 read from its FIFO, with the Madgwick it ran before issue 27 (beta 0.1):
    these tests are about an AHRS with a compiled row kernel, whose estimates of a read come
    out as one AttitudeBlock. The profile's own `decoupled` steps frame by frame."""
    profile = imu_read_from_fifo(registry, "gy91.yaml", FIFO_FRAMES)
    ahrs = profile.estimators["ahrs"].model_copy(
        update={"estimator": "madgwick", "settings": {"beta": 0.1}})
    return profile.model_copy(update={"estimators": {**profile.estimators, "ahrs": ahrs}})


@pytest.fixture(scope="module")
def run(registry: Registry) -> tuple[BoardProfile, Pipeline, list[Sample | Estimate]]:
    profile = _gy91_fifo(registry)
    with open_emulated(profile, registry, scenario="thermal", seed=2,
                       sensor_errors=True) as pipeline:
        events: list[Sample | Estimate] = list(pipeline.events(6.0))
    return profile, pipeline, events


def test_a_fifo_read_hands_out_its_frames_in_time_order_in_the_body_frame(
        run: tuple[BoardProfile, Pipeline, list[Sample | Estimate]]) -> None:
    _, _, events = run
    imu = [e for e in events if isinstance(e, AccelSample | GyroSample) and e.device == "imu"]
    gyro_t = [e.t_ns for e in imu if isinstance(e, GyroSample)]
    assert all(e.frame is Frame.BODY_NED for e in imu)
    # frames of one read are one chip period apart (stamped from the chip's clock: the
    # emulated oscillator is off by up to 2 %, so the period is learned, not the nominal one)
    # and come out frame by frame (accel, then gyro of each frame: the chip's own order), not
    # stream by stream
    steps = [b - a for a, b in pairwise(gyro_t)]
    assert all(0.97 * PERIOD_NS < step < 1.03 * PERIOD_NS for step in steps)
    kinds = [type(e) for e in imu[:2 * FIFO_FRAMES]]
    assert kinds == [AccelSample, GyroSample] * FIFO_FRAMES


def test_the_offline_chain_over_a_fifo_runs_samples_gives_its_live_estimates(
        registry: Registry,
        run: tuple[BoardProfile, Pipeline, list[Sample | Estimate]]) -> None:
    """The router's rule for blocks is the offline chain's rule for single samples: the
    same estimates, to the bit. Live, each FIFO read's accelerometer and gyro blocks go to
    Madgwick at once (``update_blocks``; reads of 8 frames, fewer than its compiled row
    kernel pays for, then go frame by frame there) and its estimates then to vario-kf3;
    offline, every sample goes on its own."""
    profile, pipeline, events = run
    samples = [e for e in events if isinstance(e, Sample) and e.valid]
    live = [e for e in events if isinstance(e, Estimate)]
    offline = offline_estimates(registry, profile, pipeline.streams, samples)

    assert sum(isinstance(e, AttitudeEstimate) for e in live) > 900
    assert sum(isinstance(e, VerticalEstimate) for e in live) > 100
    assert offline == live


def test_blocks_hands_out_each_read_as_blocks_with_the_frames_and_estimates_of_events(
        registry: Registry,
        run: tuple[BoardProfile, Pipeline, list[Sample | Estimate]]) -> None:
    """``Pipeline.blocks()``: each FIFO read as one block per stream, whose one-row views are
    the frames ``events()`` hands out, Madgwick's estimates of a read as one AttitudeBlock
    whose rows are the estimates ``events()`` hands out, and every other event as
    ``events()`` gives it, in the same order; the start-up phase (the GY-91 measures its
    gyro offsets) runs as under ``events()``."""
    profile, _, events = run
    with open_emulated(profile, registry, scenario="thermal", seed=2,
                       sensor_errors=True) as pipeline:
        items = list(pipeline.blocks(6.0))
    blocks = [b for b in items if isinstance(b, Block)]
    assert sum(len(b) for b in blocks) > 1000
    assert all(len(b) > 1 for b in blocks[1:])  # the first may be a read's rest
    attitude_blocks = [b for b in items if isinstance(b, AttitudeBlock)]
    assert sum(len(b) for b in attitude_blocks) > 900
    expanded = [s for item in items
                for s in (item.samples() if isinstance(item, Block) else
                          item.rows() if isinstance(item, AttitudeBlock) else [item])]

    def by_stream(seq: list[object]) -> dict[tuple[str, str], list[str]]:
        out: dict[tuple[str, str], list[str]] = {}
        for e in seq:
            out.setdefault((getattr(e, "device", ""), type(e).__name__), []).append(repr(e))
        return out

    # a read's blocks come stream by stream, events() interleaves their frames: the same
    # events per stream and in order, and the same sequence once reads are interleaved
    assert by_stream(expanded) == by_stream(list(events))
    assert [repr(e) for e in expanded if not isinstance(e, AccelSample | GyroSample)] == \
        [repr(e) for e in events if not isinstance(e, AccelSample | GyroSample)]


def test_each_fifo_read_reaches_the_estimators_whole_in_one_fusion_step(
        registry: Registry, monkeypatch: pytest.MonkeyPatch) -> None:
    """A read's frames are fused in one step (the magnetometer's and barometer's polls
    between two reads do not split it at their due times): every gyro block the router
    gets is a whole read's gyro block. (Spies on the driver's and the router's calls; no
    behaviour changed.)"""
    read: list[int] = []
    fused: list[int] = []
    poll_blocks = MPU9250Driver.poll_blocks
    fuse_blocks = Router.fuse_blocks

    def polled(self: MPU9250Driver, now_ns: int) -> BlockPoll:
        got = poll_blocks(self, now_ns)
        read.extend(len(b) for b in got.blocks if b.kind is GyroSample and len(b) > 1)
        return got

    def routed(self: Router, blocks: Sequence[Block], out: list[Estimate],
               **options: bool) -> None:
        fused.extend(len(b) for b in blocks if b.kind is GyroSample and len(b) > 1)
        fuse_blocks(self, blocks, out, **options)

    monkeypatch.setattr(MPU9250Driver, "poll_blocks", polled)
    monkeypatch.setattr(Router, "fuse_blocks", routed)
    with open_emulated(_gy91_fifo(registry), registry, scenario="thermal", seed=2) as pipeline:
        for _ in pipeline.blocks(4.0):
            pass
    assert len(read) > 60
    # the start-up phase (gyro offsets) ends inside the first read: its frames after that
    # are fused together; every later read whole
    assert 0 < fused[0] < read[0]
    assert fused[1:] == read[1:]


class _Kept:
    """A sink that keeps every event."""

    def __init__(self) -> None:
        self.events: list[object] = []

    def handle(self, event: object) -> None:
        self.events.append(event)

    def close(self) -> None:
        pass


def test_a_run_without_sinks_counts_what_a_run_with_one_counts(registry: Registry) -> None:
    """``run`` with no sink iterates ``blocks()`` (no sample built per FIFO frame): the same
    samples, flags, frames and estimates in its summary as a run whose sink takes every
    event."""
    profile = _gy91_fifo(registry)
    kept = _Kept()
    summaries = []
    for sinks in ([], [kept]):
        with open_emulated(profile, registry, scenario="thermal", seed=2) as pipeline:
            summaries.append(pipeline.run(3.0, sinks))
    bare, with_sink = summaries
    assert len(kept.events) > 1000
    assert bare.samples == with_sink.samples and bare.samples["imu"] > 1000
    assert (bare.flagged, bare.frames, bare.estimates) == \
        (with_sink.flagged, with_sink.frames, with_sink.estimates)
