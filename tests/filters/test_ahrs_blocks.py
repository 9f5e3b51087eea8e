"""``update_blocks`` of the AHRS family gives what ``process()`` gives frame by frame.

A fusion step's accelerometer, magnetometer and gyro blocks (a FIFO read) go through the
filter's compiled row kernel in one call once it is aligned (turn compensation by a nominal
airspeed included); the reference is the same
frames, in fusion order, through ``process()`` one by one. On conformance data set A cut
into steps of 37 frames, with the awkward cases added (a slower and a missing
magnetometer, values beyond the full scale, a time jump, a repeated time stamp, an
accelerometer that goes stale, the board still for a while: rest detection), every estimate
equals the reference's to 1e-12 (the same time, diagnostics of the same keys and types) and
the estimator ends in the same state (the rest detector's bit for bit).
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest
from tests.filters.dataset_a import load_head

from imuhal.core.blocks import Block
from imuhal.core.samples import AccelSample, Frame, GyroSample, MagSample, VelocitySample
from imuhal.estimation.ordering import fusion_order
from imuhal.estimation.outputs import AttitudeEstimate, Estimate
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


def _same(got: list[Estimate], ref: list[Estimate]) -> None:
    assert len(got) == len(ref)
    for e, r in zip(got, ref, strict=True):
        assert isinstance(e, AttitudeEstimate) and isinstance(r, AttitudeEstimate)
        assert e.t_ns == r.t_ns and e.source == r.source
        assert e.q_body_to_ned == pytest.approx(r.q_body_to_ned, rel=0, abs=1e-12)
        if r.linear_accel_ned_m_s2 is None:
            assert e.linear_accel_ned_m_s2 is None
        else:
            assert e.linear_accel_ned_m_s2 == pytest.approx(r.linear_accel_ned_m_s2,
                                                            rel=0, abs=1e-12)
        assert list(e.diagnostics) == list(r.diagnostics)
        for key, value in r.diagnostics.items():
            assert type(e.diagnostics[key]) is type(value), key
            if isinstance(value, float | tuple):
                assert e.diagnostics[key] == pytest.approx(value, rel=0, abs=1e-12), key
            else:
                assert e.diagnostics[key] == value, key


def _same_state(est: AhrsEstimator, ref: AhrsEstimator) -> None:
    state, ref_state = est.get_state(), ref.get_state()
    assert state["counters"] == ref_state["counters"]
    assert state["q"] == pytest.approx(ref_state["q"], rel=0, abs=1e-12)
    for key in ("last_gyro_t_ns", "accel_m_s2", "accel_t_ns", "mag_ut", "mag_t_ns", "aligned",
                "kinematics", "rest", "at_rest"):
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
    """``update_blocks`` of every step of ``steps``: how many times the row kernel ran."""
    calls = 0
    run = est._run_kernel

    def counted(*args: Any) -> bool:
        nonlocal calls
        calls += 1
        return run(*args)

    est._run_kernel = counted  # type: ignore[method-assign]
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
    long_enough = [s for s in steps
                   if len(s[-1]) >= ahrs.MIN_KERNEL_FRAMES_COMPILED_STEP]
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
