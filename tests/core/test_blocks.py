"""Blocks: n frames of one stream; samples stay their one-row views."""

from __future__ import annotations

import numpy as np
import pytest

from imuhal.core.blocks import Block, blocks_of, interleaved
from imuhal.core.quantities import Quantity
from imuhal.core.samples import (
    AccelSample,
    Frame,
    GyroSample,
    PressureSample,
    SampleFlag,
    TemperatureSample,
    VelocitySample,
)
from imuhal.core.streams import StreamSpec

SPEC = StreamSpec(device="imu", quantity=Quantity.GYRO, frame=Frame.SENSOR, rate_hz=1000.0,
                  scale=1e-3, full_scale=8.7)


def _gyro(t_ns: int, x: float, flags: SampleFlag = SampleFlag.OK) -> GyroSample:
    return GyroSample(t_ns=t_ns, device="imu", flags=flags, gyro_rad_s=(x, -x, 0.5 * x))


def test_a_block_of_samples_gives_them_back_as_its_rows_and_as_arrays() -> None:
    rows = [_gyro(1_000, 0.1), _gyro(2_000, 0.2, SampleFlag.SATURATED), _gyro(3_000, 0.3)]
    block = Block.from_samples(rows, SPEC)
    assert block.samples() == rows
    assert len(block) == 3 and block.t0_ns == 1_000
    assert block.t_ns.tolist() == [1_000, 2_000, 3_000]
    assert block.values.tolist() == [list(r.gyro_rad_s) for r in rows]
    assert block.flags.tolist() == [0, int(SampleFlag.SATURATED), 0]
    assert block.quantity is Quantity.GYRO and block.unit == "rad/s"
    assert block.frame is Frame.SENSOR and block.spec is SPEC


def test_a_block_from_arrays_has_one_sample_view_per_frame() -> None:
    values = np.array([[1.0, 2.0, 3.0], [4.0, 5.0, 6.0]])
    block = Block.regular(AccelSample, "imu", 5_000, 1_000_000, values,
                          np.array([0, int(SampleFlag.NAN)]), frame=Frame.BODY_NED)
    a, b = block.samples()
    assert a == AccelSample(t_ns=5_000, device="imu", frame=Frame.BODY_NED,
                            accel_m_s2=(1.0, 2.0, 3.0))
    assert b == AccelSample(t_ns=1_005_000, device="imu", frame=Frame.BODY_NED,
                            flags=SampleFlag.NAN, accel_m_s2=(4.0, 5.0, 6.0))


def test_a_scalar_block_holds_one_column() -> None:
    block = Block.regular(PressureSample, "baro", 0, 10_000_000, np.array([[90000.0], [90001.5]]),
                          frame=None)
    assert [s.pressure_pa for s in block.samples()] == [90000.0, 90001.5]
    assert Block.from_samples(block.samples()).values.shape == (2, 1)


def test_select_keeps_the_chosen_frames_with_their_times() -> None:
    block = Block.regular(GyroSample, "imu", 100, 10, np.arange(12.0).reshape(4, 3),
                          frame=Frame.SENSOR)
    kept = block.select(np.array([False, True, False, True]))
    assert kept is not None
    assert kept.t_ns.tolist() == [110, 130]
    assert kept.values[:, 0].tolist() == [3.0, 9.0]
    assert block.select(np.ones(4, bool)) is block
    assert block.select(np.zeros(4, bool)) is None


def test_one_block_per_stream_in_order_of_first_appearance() -> None:
    a0 = AccelSample(t_ns=0, device="imu")
    g0, g1 = _gyro(0, 1.0), _gyro(10, 2.0)
    t0 = TemperatureSample(t_ns=0, device="imu", temperature_degc=25.0)
    a1 = AccelSample(t_ns=10, device="imu")
    blocks = blocks_of([a0, g0, t0, a1, g1])
    assert [(b.kind, b.samples()) for b in blocks] == [
        (AccelSample, [a0, a1]), (GyroSample, [g0, g1]), (TemperatureSample, [t0])]
    # a FIFO's frames come back out frame by frame, as the chip held them
    assert interleaved(blocks) == [a0, g0, t0, a1, g1]


def test_samples_with_more_than_one_value_travel_as_rows() -> None:
    fix = VelocitySample(t_ns=7, device="gnss", velocity_ned_m_s=(1.0, 2.0, 0.0))
    (block,) = blocks_of([fix])
    assert block.samples() == [fix]
    with pytest.raises(ValueError, match="more than one value"):
        Block.regular(VelocitySample, "gnss", 0, 1, np.zeros((1, 3)), frame=None)


def test_a_block_holds_one_stream_and_frames_that_do_not_go_back() -> None:
    with pytest.raises(ValueError, match="one stream"):
        Block.from_samples([_gyro(0, 1.0), AccelSample(t_ns=0, device="imu")])
    with pytest.raises(ValueError, match="back in time"):
        Block.from_arrays(GyroSample, "imu", 0, np.array([0, 5, 3]), np.zeros((3, 3)),
                          np.zeros(3, np.int64), frame=Frame.SENSOR)
    with pytest.raises(ValueError, match="do not make"):
        Block.from_arrays(GyroSample, "imu", 0, np.array([0, 5]), np.zeros((3, 3)),
                          np.zeros(2, np.int64), frame=Frame.SENSOR)


def test_flagged_says_whether_some_frame_has_a_flag_in_every_form_of_a_block() -> None:
    """``Block.flagged`` is ``flags.any()`` of the block it is asked of, whether the block
    was built from arrays, from samples or from one sample, or derived with new values or
    new flags."""
    t = np.arange(3, dtype=np.int64) * 4_000_000
    clean = Block.from_arrays(GyroSample, "imu", 0, t, np.zeros((3, 3)),
                              np.zeros(3, np.int64), frame=Frame.SENSOR)
    assert not clean.flagged
    assert not clean.with_values(np.ones((3, 3)), Frame.BODY_NED).flagged
    one = clean.with_flags(np.array([0, int(SampleFlag.NAN), 0], np.int64))
    assert one.flagged and one.with_values(np.ones((3, 3)), Frame.BODY_NED).flagged
    assert Block.of_sample(_gyro(0, 1.0, SampleFlag.STALE)).flagged
    assert not Block.of_sample(_gyro(0, 1.0)).flagged
    assert Block.from_samples([_gyro(0, 1.0), _gyro(4_000_000, 1.0, SampleFlag.NAN)]).flagged
