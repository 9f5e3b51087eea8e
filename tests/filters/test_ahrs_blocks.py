"""``update_blocks`` of the AHRS family gives what ``process()`` gives frame by frame.

A fusion step's accelerometer, magnetometer and gyro blocks (a FIFO read) go through the
filter's compiled row kernel in one call once it is aligned (turn compensation by a nominal
airspeed included); the reference is the same
frames, in fusion order, through ``process()`` one by one. On conformance data set A cut
into steps of 37 frames, with the awkward cases added (a slower and a missing
magnetometer, values beyond the full scale, a time jump, a repeated time stamp, an
accelerometer that goes stale, the board still for a while: rest detection), every estimate
equals the reference's to 1e-12 (the same time, diagnostics of the same keys and types) and
the estimator ends in the same state (the rest detector's bit for bit). Madgwick's compiled
block step (FIFO reads of 8 frames, every stream at the gyro's instants or a magnetometer
held from its own steps) gives the very floats of ``process()``.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest
from tests.filters.dataset_a import load_head

from imuhal.core.blocks import Block
from imuhal.core.samples import AccelSample, Frame, GyroSample, MagSample, VelocitySample
from imuhal.estimation.ordering import fusion_order
from imuhal.estimation.outputs import (
    AttitudeBlock,
    AttitudeEstimate,
    Estimate,
    estimate_flags,
    rows_of,
)
from imuhal.plugins.manager import load_registry
from imuhal_filters.common import ahrs
from imuhal_filters.common.ahrs import AhrsEstimator

STEP = 37
CASES = [
    ("madgwick", {}),
    ("madgwick", {"preset": "seed"}),
    ("madgwick", {"use_mag": False, "max_aux_age_s": 0.02}),
    ("madgwick", {"dt_from_timestamps": False, "turn_compensation": False}),
    ("mahony", {}),
    ("mahony", {"ki": 0.2, "accel_gate_g": (0.8, 1.2)}),
    ("imufilter", {}),
    ("imufilter", {"velocity": True}),
    # turn compensation by the nominal airspeed (the seed varios' Madgwick): the kernel
    # fuses the compensated specific force
    ("madgwick", {"nominal_airspeed_m_s": 10.0}),
    ("madgwick", {"preset": "seed", "nominal_airspeed_m_s": 10.0}),
    ("mahony", {"nominal_airspeed_m_s": 10.0}),
    ("imufilter", {"nominal_airspeed_m_s": 10.0}),
]


def _steps(with_mag: bool = True) -> list[list[Block]]:
    t, gyro, accel, mag, _ = load_head()
    n = min(1500, len(t))
    t_ns = np.round(t[:n] * 1e9).astype(np.int64)
    gyro, accel, mag = gyro[:n].copy(), accel[:n].copy(), mag[:n].copy()
    gyro[500, 1] = 1e9                   # an impossible gyro value: no step, counted
    accel[600, 2] = 1e6                  # an impossible accel value: the held one is used
    accel[700:760] = (0.0, 0.0, 1e5)     # 60 impossible accel frames: the held one goes stale
    accel[800] = (0.0, 0.0, -25.0)       # 2.5 g: a hard gate closes
    mag[5, 1] = np.inf                   # an impossible magnetometer value
    t_ns[900:] += 500_000_000            # a time jump: nominal step, counted
    t_ns[1000] = t_ns[999]               # a repeated time stamp: nominal step, counted
    has_mag = np.ones(n, dtype=bool)
    has_mag[1::3] = False                # a slower magnetometer
    has_mag[300:380] = False             # the magnetometer goes quiet: held, then stale
    steps = []
    for i in range(0, n, STEP):
        rows = slice(i, min(i + STEP, n))
        step = [_block(AccelSample, t_ns[rows], accel[rows]),
                _block(GyroSample, t_ns[rows], gyro[rows])]
        m = has_mag[rows]
        if with_mag and m.any():
            step.insert(1, _block(MagSample, t_ns[rows][m], mag[rows][m]))
        steps.append(step)
    return steps


def _block(kind: type, t_ns: np.ndarray, values: np.ndarray) -> Block:
    return Block.from_arrays(kind, "imu", int(t_ns[0]), t_ns - t_ns[0], values,
                             np.zeros(len(t_ns), np.int64), frame=Frame.BODY_NED)


def _frame_by_frame(est: AhrsEstimator, steps: list[list[Block]]) -> list[Estimate]:
    out: list[Estimate] = []
    for step in steps:
        for s in fusion_order([s for b in step for s in b.samples()]):
            out += est.process(s)
    return out


def _same(got: list[Estimate], ref: list[Estimate], tol: float = 1e-12) -> None:
    assert len(got) == len(ref)
    for e, r in zip(got, ref, strict=True):
        assert isinstance(e, AttitudeEstimate) and isinstance(r, AttitudeEstimate)
        assert e.t_ns == r.t_ns and e.source == r.source
        assert e.q_body_to_ned == pytest.approx(r.q_body_to_ned, rel=0, abs=tol)
        if r.linear_accel_ned_m_s2 is None:
            assert e.linear_accel_ned_m_s2 is None
        else:
            assert e.linear_accel_ned_m_s2 == pytest.approx(r.linear_accel_ned_m_s2,
                                                            rel=0, abs=tol)
        assert list(e.diagnostics) == list(r.diagnostics)
        for key, value in r.diagnostics.items():
            assert type(e.diagnostics[key]) is type(value), key
            if isinstance(value, float | tuple):
                assert e.diagnostics[key] == pytest.approx(value, rel=0, abs=tol), key
            else:
                assert e.diagnostics[key] == value, key


def _same_state(est: AhrsEstimator, ref: AhrsEstimator) -> None:
    state, ref_state = est.get_state(), ref.get_state()
    assert state["counters"] == ref_state["counters"]
    assert state["q"] == pytest.approx(ref_state["q"], rel=0, abs=1e-12)
    for key in ("last_gyro_t_ns", "accel_m_s2", "accel_t_ns", "mag_ut", "mag_t_ns", "aligned",
                "kinematics", "rest", "at_rest", "step_accel_m_s2"):
        assert state[key] == ref_state[key], key


def _pair(name: str, settings: dict[str, Any]) -> tuple[AhrsEstimator, AhrsEstimator]:
    cls = load_registry().estimators.get(name)
    return cls(cls.Settings(**settings)), cls(cls.Settings(**settings))


@pytest.mark.parametrize(("name", "settings"), CASES,
                         ids=[f"{n}-{','.join(map(str, s.values())) or 'defaults'}"
                              for n, s in CASES])
def test_update_blocks_gives_the_estimates_of_the_frames_one_by_one(
        name: str, settings: dict[str, Any], compiled_backend: str) -> None:
    est, ref = _pair(name, settings)
    steps = _steps()
    got: list[Estimate] = []
    for step in steps:
        got += est.update_blocks(step)
    _same(got, _frame_by_frame(ref, steps))
    _same_state(est, ref)


def test_a_6dof_fifo_read_gives_the_estimates_of_the_frames_one_by_one(
        compiled_backend: str) -> None:
    est, ref = _pair("madgwick", {})
    steps = _steps(with_mag=False)
    got: list[Estimate] = []
    for step in steps:
        got += est.update_blocks(step)
    _same(got, _frame_by_frame(ref, steps))
    _same_state(est, ref)


def test_a_gyro_block_alone_steps_with_the_held_accelerometer(compiled_backend: str) -> None:
    est, ref = _pair("madgwick", {})
    steps = _steps()
    head, rest = steps[:3], steps[3:]
    _frame_by_frame(est, head)
    _frame_by_frame(ref, head)
    gyro_only = [[b for b in step if b.kind is GyroSample] for step in rest[:2]]
    got = [e for step in gyro_only for e in est.update_block(step[0])]
    _same(got, _frame_by_frame(ref, gyro_only))
    assert est.get_state()["counters"]["stale_accel"] > 0  # the held one went stale


def _kernel_calls(est: AhrsEstimator, steps: list[list[Block]]) -> int:
    """``update_blocks`` of every step of ``steps``: how many times a compiled kernel ran
    (the row kernel, or the block step where it took the step)."""
    calls = 0
    run, block_step = est._run_kernel, est._block_step

    def counted(*args: Any) -> bool:
        nonlocal calls
        calls += 1
        return run(*args)

    def counted_block(*args: Any) -> Any:
        nonlocal calls
        done = block_step(*args)
        calls += done is not None
        return done

    est._run_kernel = counted  # type: ignore[method-assign]
    est._block_step = counted_block  # type: ignore[method-assign]
    for step in steps:
        est.update_blocks(step)
    return calls


@pytest.mark.parametrize("settings", [{}, {"nominal_airspeed_m_s": 10.0}],
                         ids=["defaults", "nominal-airspeed"])
def test_the_compiled_row_kernel_takes_the_aligned_steps(settings: dict[str, Any],
                                                         compiled_backend: str) -> None:
    """The comparisons above are of the block path: every step's gyro block runs in the
    kernel (one call per step), the first one's after its first frames went one by one
    to align the filter; only a last step shorter than the kernel's break-even (the
    compiled per-sample step runs in these tests) goes frame by frame."""
    est, _ = _pair("madgwick", settings)
    steps = _steps()
    least = ahrs.MIN_BLOCK_STEP_FRAMES if est._has_block_step() else \
        ahrs.MIN_KERNEL_FRAMES_COMPILED_STEP
    long_enough = [s for s in steps if len(s[-1]) >= least]
    assert len(long_enough) >= len(steps) - 1
    assert _kernel_calls(est, steps) == len(long_enough)
    assert est.get_state()["kinematics"]["counts"]["compensated_steps"] == (
        0 if not settings else est.get_state()["counters"]["steps"])


def test_nominal_turn_compensation_moves_the_estimates() -> None:
    """The nominal-airspeed cases above compare something: the compensation changes the
    attitude on this data (a comparison that ignored it would fail)."""
    plain, _ = _pair("madgwick", {})
    turned, _ = _pair("madgwick", {"nominal_airspeed_m_s": 10.0})
    steps = _steps()
    a, b = _frame_by_frame(plain, steps), _frame_by_frame(turned, steps)
    assert len(a) == len(b)
    assert max(abs(x - y) for e, f in zip(a, b, strict=True)
               for x, y in zip(e.q_body_to_ned, f.q_body_to_ned, strict=True)) > 1e-3  # type: ignore[attr-defined]


def test_a_velocity_source_sends_the_blocks_frame_by_frame(compiled_backend: str) -> None:
    """Turn compensation by a ground velocity (its circle fit and slope) is not in the row
    kernel: once a velocity sample has come, the blocks go through ``process()``."""
    est, _ = _pair("madgwick", {"nominal_airspeed_m_s": 10.0})
    steps = _steps()
    est.update_blocks(steps[0])
    est.process(VelocitySample(t_ns=int(steps[0][0].t_ns[-1]), device="gnss",
                               velocity_ned_m_s=(10.0, 0.0, 0.0)))
    assert _kernel_calls(est, steps[1:]) == 0


def test_the_log_exercises_every_case_the_blocks_resolve() -> None:
    """The comparisons above cannot pass by missing a case: the reference meets each one."""
    est, _ = _pair("madgwick", {})
    _frame_by_frame(est, _steps())
    counters = est.get_state()["counters"]
    assert counters["stale_accel"] > 0
    assert counters["stale_mag"] > 0
    assert counters["dt_fallbacks"] == 2
    assert counters["beyond_full_scale"] == {"gyro": 1, "accel": 61, "mag": 1}
    assert est.get_state()["rest"][8] > 1.0  # the board lay still over a second: at rest
    seed, _ = _pair("madgwick", {"preset": "seed"})  # the one with a hard gate
    _frame_by_frame(seed, _steps())
    assert seed.get_state()["counters"]["gate_closed_steps"] > 0


def _fifo_reads(frames: int, with_mag: str) -> list[list[Block]]:
    """The log cut into FIFO reads of ``frames`` frames of gyro and accelerometer at the
    same instants; ``with_mag`` "in": the magnetometer's too (read through the IMU's own
    I2C master), "apart": one magnetometer frame in a step of its own before every third
    read (a magnetometer on its own bus: held, and stale while it is quiet), "": none. With
    the awkward frames
    of ``_steps`` (clipped gyro and accelerometer values, stale held frames, a time jump, a
    repeated time stamp, a hard gate, the board still: rest detection)."""
    t, gyro, accel, mag, _ = load_head()
    n = min(1500, len(t))
    t_ns = np.round(t[:n] * 1e9).astype(np.int64)
    gyro, accel, mag = gyro[:n].copy(), accel[:n].copy(), mag[:n].copy()
    gyro[500, 1] = 1e9
    accel[600, 2] = 1e6
    accel[700:760] = (0.0, 0.0, 1e5)
    accel[800] = (0.0, 0.0, -25.0)
    mag[5, 1] = np.inf
    t_ns[900:] += 500_000_000
    t_ns[1000] = t_ns[999]
    reads = []
    for i in range(0, n, frames):
        rows = slice(i, min(i + frames, n))
        read = [_block(AccelSample, t_ns[rows], accel[rows]),
                _block(GyroSample, t_ns[rows], gyro[rows])]
        if with_mag == "in":
            read.insert(1, _block(MagSample, t_ns[rows], mag[rows]))
        k = i // frames
        if with_mag == "apart" and k % 3 == 0 and not 40 <= k < 60:
            reads.append([_block(MagSample, t_ns[i:i + 1], mag[i:i + 1])])
        reads.append(read)
    return reads


FIFO_CASES = [
    ({}, "in"),
    ({}, "apart"),
    ({}, ""),
    ({"preset": "seed"}, "apart"),
    ({"nominal_airspeed_m_s": 10.0}, "apart"),
    ({"nominal_airspeed_m_s": 10.0}, "in"),
    ({"nominal_airspeed_m_s": 10.0, "use_mag": False}, "in"),
    ({"dt_from_timestamps": False, "max_aux_age_s": None}, "apart"),
]


@pytest.mark.parametrize(("settings", "with_mag"), FIFO_CASES,
                         ids=[f"{','.join(map(str, s.values())) or 'defaults'}-mag-"
                              f"{m or 'none'}" for s, m in FIFO_CASES])
def test_fifo_reads_through_the_block_step_equal_the_frames_one_by_one_bit_for_bit(
        settings: dict[str, Any], with_mag: str, compiled_backend: str) -> None:
    """Madgwick's compiled block step (bookkeeping, turn compensation by the nominal
    airspeed, steps and gravity-compensated acceleration in one call) on FIFO reads of 8
    frames: the very floats of ``process()``, the same counters, held frames, turn and rest
    state; and it took most reads (the awkward ones go through ``block_rows``)."""
    est, ref = _pair("madgwick", settings)
    reads = _fifo_reads(8, with_mag)
    imu_reads = sum(1 for read in reads if len(read) > 1)
    taken = 0
    block_step = est._block_step

    def counted(*args: Any) -> Any:
        nonlocal taken
        done = block_step(*args)
        taken += done is not None
        return done

    est._block_step = counted  # type: ignore[method-assign]
    got: list[Estimate] = []
    for read in reads:
        got += est.update_blocks(read)
    _same(got, _frame_by_frame(ref, reads), tol=0.0)
    state, ref_state = est.get_state(), ref.get_state()
    assert state["q"] == ref_state["q"]
    _same_state(est, ref)
    assert taken > imu_reads // 2


def test_the_fifo_reads_exercise_what_the_block_step_resolves() -> None:
    """The bit-for-bit comparisons above cannot pass by missing a case: frame by frame, the
    reads clip, hold, go stale, fall back to the nominal step, close the gate, rest and
    compensate turns."""
    est, _ = _pair("madgwick", {"nominal_airspeed_m_s": 10.0})
    _frame_by_frame(est, _fifo_reads(8, "apart"))
    state = est.get_state()
    counters = state["counters"]
    assert counters["stale_accel"] > 0 and counters["stale_mag"] > 0
    assert counters["dt_fallbacks"] == 2
    assert counters["beyond_full_scale"] == {"gyro": 1, "accel": 61}
    assert state["kinematics"]["counts"]["compensated_steps"] == counters["steps"]
    assert state["rest"][8] > 1.0  # the board lay still over a second: at rest
    seed, _ = _pair("madgwick", {"preset": "seed"})  # the one with a hard gate
    _frame_by_frame(seed, _fifo_reads(8, "apart"))
    assert seed.get_state()["counters"]["gate_closed_steps"] > 0


@pytest.mark.parametrize(("settings", "with_mag"), FIFO_CASES[:2] + FIFO_CASES[4:6],
                         ids=[f"{','.join(map(str, s.values())) or 'defaults'}-mag-{m}"
                              for s, m in FIFO_CASES[:2] + FIFO_CASES[4:6]])
def test_estimate_blocks_rows_are_the_estimates_of_update_blocks_bit_for_bit(
        settings: dict[str, Any], with_mag: str, compiled_backend: str) -> None:
    """``estimate_blocks`` (the live pipeline's call) gives each read the block step takes
    as one AttitudeBlock whose rows are the very estimates ``update_blocks`` makes of it
    (quaternions, accelerations, diagnostics: the same floats), and the estimator ends in
    the same state."""
    est, ref = _pair("madgwick", settings)
    got: list[Any] = []
    want: list[Estimate] = []
    for read in _fifo_reads(8, with_mag):
        got += est.estimate_blocks(read)
        want += ref.update_blocks(read)
    blocks = [e for e in got if isinstance(e, AttitudeBlock)]
    assert sum(len(b) for b in blocks) > len(want) // 2
    assert all(len(b) == 8 for b in blocks)
    rows = rows_of(got)
    _same(rows, want, tol=0.0)
    assert [repr(e) for e in rows] == [repr(e) for e in want]
    assert est.get_state()["q"] == ref.get_state()["q"]
    _same_state(est, ref)


def test_an_attitude_block_is_usable_only_when_every_row_passes_the_estimate_check() -> None:
    """``AttitudeBlock.all_usable`` is ``estimate_flags`` of every row at once: one row with
    a NaN acceleration, an infinite or a zero quaternion makes the block unusable."""
    t = np.arange(4, dtype=np.int64) * 5_000_000
    q = np.tile([1.0, 0.0, 0.0, 0.0], (4, 1))
    lin = np.zeros((4, 3))

    def block(q: np.ndarray, lin: np.ndarray | None) -> AttitudeBlock:
        return AttitudeBlock("ahrs", t, q, lin, lambda: [{} for _ in range(4)])

    assert block(q, lin).all_usable() and block(q, None).all_usable()
    for bad_q, bad_lin in ((q, np.where(np.arange(4)[:, None] == 2, np.nan, lin)),
                           (np.where(np.arange(4)[:, None] == 1, np.inf, q), lin),
                           (np.where(np.arange(4)[:, None] == 3, 0.0, q), lin)):
        b = block(bad_q, bad_lin)
        assert not b.all_usable()
        assert [bool(estimate_flags(e)) for e in b.rows()].count(True) == 1
