"""Validity, calibration and rotation once per block give, frame for frame, the floats and
flags the per-sample steps give (the pipeline takes either form of one-frame blocks)."""

from __future__ import annotations

import numpy as np
import pytest

from imuhal.calibration.model import (
    AccelCalibration,
    DeviceCalibration,
    GyroCalibration,
    MagCalibration,
)
from imuhal.core.blocks import Block
from imuhal.core.quantities import Quantity
from imuhal.core.samples import (
    AccelSample,
    Frame,
    GyroSample,
    MagSample,
    PositionSample,
    Sample,
    SampleFlag,
    VectorSample,
)
from imuhal.core.streams import StreamSpec
from imuhal.pipeline.processing import (
    calibrate_block,
    calibrate_to_body,
    validity_block,
    validity_flags,
)

CALIBRATION = DeviceCalibration(
    accel=AccelCalibration(offset_m_s2=(0.11, -0.07, 0.23), scale=(1.01, 0.993, 1.004),
                           misalignment=((1.0, 0.012, -0.004), (0.003, 1.0, 0.009),
                                         (-0.011, 0.002, 1.0))),
    gyro=GyroCalibration(offset_rad_s=(0.003, -0.002, 0.0011), scale=(0.998, 1.002, 1.0),
                         misalignment=((1.0, 0.001, 0.0), (0.0, 1.0, -0.002),
                                       (0.004, 0.0, 1.0))),
    mag=MagCalibration(hard_iron_ut=(12.5, -3.25, 40.0),
                       soft_iron=((1.05, 0.02, -0.01), (0.02, 0.97, 0.015),
                                  (-0.01, 0.015, 1.01))),
)
# a mount that is no signed permutation: every component mixes all three
_c, _s = np.cos(0.3), np.sin(0.3)
CHIP_TO_BODY = (np.array([[1, 0, 0], [0, _c, -_s], [0, _s, _c]])
                @ np.array([[_c, 0, _s], [0, 1, 0], [-_s, 0, _c]])).tolist()


def _frames(kind: type[VectorSample], n: int, seed: int) -> list[Sample]:
    rng = np.random.default_rng(seed)
    values = rng.normal(0.0, 5.0, (n, 3))
    flags = rng.choice([0, 0, 0, int(SampleFlag.SATURATED), int(SampleFlag.STALE)], n)
    return [kind.build(1_000_000 * (i + 1), "imu", SampleFlag(int(f)), Frame.SENSOR,
                       (float(v[0]), float(v[1]), float(v[2])))
            for i, (v, f) in enumerate(zip(values, flags, strict=True))]


def _as_arrays(block: Block) -> Block:
    """The same frames, built from arrays (as a FIFO reader builds them)."""
    return Block.from_arrays(block.kind, block.device, block.t0_ns, block.offsets_ns,
                             block.values.copy(), block.flags.copy(), frame=block.frame)


def _unflagged(rows: list[Sample]) -> list[Sample]:
    return [GyroSample.build(s.t_ns, s.device, SampleFlag.OK, Frame.SENSOR,
                             s.vector)  # type: ignore[attr-defined]
            for s in rows]


def _bits(samples: list[Sample]) -> list[tuple[int, int, bytes]]:
    return [(s.t_ns, int(s.flags), np.array(s.vector).tobytes())  # type: ignore[attr-defined]
            for s in samples]


@pytest.mark.parametrize("kind", [AccelSample, GyroSample, MagSample])
def test_calibrating_a_block_gives_the_floats_of_each_sample_calibrated(
        kind: type[VectorSample]) -> None:
    rows = _frames(kind, 64, seed=len(kind.__name__))
    one_by_one = [calibrate_to_body(s, CALIBRATION if s.valid else None, CHIP_TO_BODY)
                  for s in rows]
    block = calibrate_block(_as_arrays(Block.from_samples(rows)), CALIBRATION, CHIP_TO_BODY)
    assert block.frame is Frame.BODY_NED
    assert _bits(block.samples()) == _bits(one_by_one)  # bit for bit, signed zeros too


SEED_MOUNT = [[0.0, -1.0, 0.0], [-1.0, 0.0, 0.0], [0.0, 0.0, -1.0]]
"""The seed board's IMU mount: a signed permutation of the axes (calibrate_block's quick
path)."""
STARTUP_GYRO = DeviceCalibration(gyro=GyroCalibration(offset_rad_s=(0.5, -0.25, 0.0)))
"""What the start-up measurement stores: an offset, unit scale, identity misalignment."""


@pytest.mark.parametrize("calibration", [None, STARTUP_GYRO, DeviceCalibration(
    gyro=GyroCalibration(offset_rad_s=(0.5, -0.25, 0.0), scale=(1.01, 0.99, 1.0)))])
def test_a_block_under_a_permuting_mount_gives_the_floats_of_each_sample(
        calibration: DeviceCalibration | None) -> None:
    rows = _unflagged(_frames(GyroSample, 16, seed=6))
    # zeros of either sign before and after the offset, which the quick path must sign as
    # the general sums do
    for i, v in enumerate([(0.0, -0.0, 0.0), (0.5, -0.25, 0.0), (-0.0, 0.0, -0.0),
                           (0.5, 0.0, -0.0)]):
        rows[i] = rows[i].with_vector(v, Frame.SENSOR)
    block = calibrate_block(_as_arrays(Block.from_samples(rows)), calibration, SEED_MOUNT)
    assert _bits(block.samples()) == _bits(
        [calibrate_to_body(s, calibration, SEED_MOUNT) for s in rows])


@pytest.mark.filterwarnings("ignore:invalid value encountered")
def test_an_infinite_value_under_a_permuting_mount_mixes_as_sample_by_sample() -> None:
    rows = _unflagged(_frames(GyroSample, 8, seed=7))
    rows[2] = rows[2].with_vector((float("inf"), 1.0, 2.0), Frame.SENSOR)
    block = calibrate_block(_as_arrays(Block.from_samples(rows)), STARTUP_GYRO, SEED_MOUNT)
    assert _bits(block.samples()) == _bits(
        [calibrate_to_body(s, STARTUP_GYRO, SEED_MOUNT) for s in rows])
    assert not np.isfinite(block.values[2]).any()  # 0.0 * inf mixed into every axis


def test_the_stages_keep_the_stream_spec_a_block_was_taken_with() -> None:
    spec = StreamSpec(device="imu", quantity=Quantity.GYRO, frame=Frame.SENSOR,
                      rate_hz=1000.0, full_scale=12.0)
    block = _as_arrays(Block.from_samples(_frames(GyroSample, 8, seed=4)))
    block.spec = spec
    checked, _ = validity_block(block, spec.full_scale, None)
    assert calibrate_block(checked, CALIBRATION, CHIP_TO_BODY).spec is spec


def test_a_block_without_calibration_is_only_rotated() -> None:
    rows = _frames(GyroSample, 8, seed=3)
    block = calibrate_block(_as_arrays(Block.from_samples(rows)), None, CHIP_TO_BODY)
    assert _bits(block.samples()) == _bits(
        [calibrate_to_body(s, None, CHIP_TO_BODY) for s in rows])


def test_validity_of_a_block_flags_what_the_per_sample_check_flags() -> None:
    rows = _frames(GyroSample, 40, seed=5)
    rows[3] = rows[3].with_vector((float("nan"), 0.0, 0.0), Frame.SENSOR)
    rows[7] = rows[7].with_vector((0.0, float("inf"), 0.0), Frame.SENSOR)
    rows[11] = rows[11].with_vector((0.0, 0.0, -30.0), Frame.SENSOR)
    full_scale, last = 12.0, rows[2].t_ns  # the previous block ended after frames 0 and 1
    expected, last_valid = _per_sample_flags(rows, full_scale, last)
    block, got_last = validity_block(_as_arrays(Block.from_samples(rows)), full_scale, last)
    assert block.flags.tolist() == expected
    assert got_last == last_valid
    assert SampleFlag.OUT_OF_ORDER in SampleFlag(expected[0])
    assert SampleFlag.NAN in SampleFlag(expected[3])
    assert SampleFlag.OUT_OF_RANGE in SampleFlag(expected[11])


def _per_sample_flags(rows: list[Sample], full_scale: float | None, last: int | None
                      ) -> tuple[list[int], int | None]:
    """The reference: each frame's flags from the per-sample check, and the last valid time."""
    expected, last_valid = [], last
    for s in rows:
        flags = validity_flags(s, full_scale, last_valid)
        if not flags:
            last_valid = s.t_ns
        expected.append(int(flags))
    return expected, last_valid


def _clean(n: int, seed: int) -> list[Sample]:
    """Unflagged gyro frames within +-12 rad/s (what a good FIFO read delivers)."""
    rng = np.random.default_rng(seed)
    return [GyroSample.build(1_000_000 * (i + 1), "imu", SampleFlag.OK, Frame.SENSOR,
                             tuple(rng.uniform(-5.0, 5.0, 3).tolist()))
            for i in range(n)]


def _set(rows: list[Sample], i: int, vector: tuple[float, float, float]) -> list[Sample]:
    rows[i] = rows[i].with_vector(vector, Frame.SENSOR)  # type: ignore[attr-defined]
    return rows


@pytest.mark.parametrize(("case", "rows", "full_scale", "last"), [
    ("all fine", _clean(10, 1), 12.0, None),
    ("a value at the full scale", _set(_clean(10, 2), 4, (0.0, -12.0, 0.0)), 12.0, None),
    ("a value beyond it", _set(_clean(10, 3), 4, (0.0, 12.000001, 0.0)), 12.0, None),
    ("a NaN", _set(_clean(10, 4), 9, (0.0, 0.0, float("nan"))), 12.0, None),
    ("an inf without a full scale", _set(_clean(10, 5), 0, (float("-inf"), 0.0, 0.0)),
     None, None),
    ("older than the last valid frame", _clean(10, 6), 12.0, 3_500_000),
    ("newer than the last valid frame", _clean(10, 7), 12.0, 1_000_000),
], ids=lambda v: v if isinstance(v, str) else "")
def test_a_clean_looking_block_is_checked_like_its_samples(
        case: str, rows: list[Sample], full_scale: float | None, last: int | None) -> None:
    """The common case's quick test (every frame unflagged, finite, within the full scale,
    not older than the last valid frame) hands on exactly what the per-sample check does,
    at each of its edges."""
    expected, last_valid = _per_sample_flags(rows, full_scale, last)
    block, got_last = validity_block(_as_arrays(Block.from_samples(rows)), full_scale, last)
    assert block.flags.tolist() == expected
    assert got_last == last_valid


def test_a_block_that_is_fine_is_handed_on_as_it_is() -> None:
    rows = [s for s in _frames(AccelSample, 10, seed=9) if s.valid]
    block = _as_arrays(Block.from_samples(rows))
    assert validity_block(block, None, None) == (block, rows[-1].t_ns)


def test_one_frame_blocks_are_checked_on_their_sample() -> None:
    sample = GyroSample(t_ns=5, device="imu", gyro_rad_s=(0.0, 40.0, 0.0))
    block, last = validity_block(Block.from_samples([sample]), 10.0, None)
    (flagged,) = block.samples()
    assert flagged == sample.flagged(SampleFlag.OUT_OF_RANGE)
    assert last is None


def test_gnss_fixes_delivered_together_are_checked_as_rows_and_stay_fixes() -> None:
    """Found by the fault matrix (seed-gps-vario, bus errors + I/O errors + all-0xFF at 1 %):
    a receiver that delivers two fixes in one poll made a two-frame block of a class with
    several values; the array check read NaN for them and the block lost its rows (an
    AssertionError ended the run)."""
    fixes = [PositionSample(t_ns=t, device="gps", latitude_deg=46.0, longitude_deg=7.0,
                            height_m=900.0) for t in (1_000, 2_000)]
    checked, last = validity_block(Block.from_samples(fixes), None, 500)
    assert checked.samples() == fixes and last == 2_000
    late, last = validity_block(Block.from_samples(fixes), None, 1_500)
    assert [s.flags for s in late.samples()] == [SampleFlag.OUT_OF_ORDER, SampleFlag.OK]
