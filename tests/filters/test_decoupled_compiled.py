"""The decoupled filter's compiled step (imuhal_filters/decoupled/fast.py) gives the Python
step's floats (core.py, the reference), bit for bit, on the AOT extension (and on numba's
JIT with ``-m long``).

One seeded 13 s case, shared: 3 s still (the rest detector and its bias updates) with a
stroke by hand (pushed, then braked back: an episode filtered again in full), then a
coordinated turn through turbulence (the manoeuvre detector closes, the look-back re-filters
and opens episodes), with the magnetometer pulled aside for 2 s (a disturbance, a
candidate reference), an accelerometer gap in the turn (the detectors start again after it)
and uneven steps. A companion test checks the case meets each of these branches, so an
equality on a case that skips them cannot pass for one that does not.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass
from functools import cache
from typing import Any

import numpy as np
import pytest
from tests.filters.ahrs_cases import FIELD_NED_UT
from tests.filters.decoupled_flight_motion import flight
from tests.filters.test_ahrs_blocks import _fifo_reads, _frame_by_frame, _pair

from imuhal.core.atmosphere import STANDARD_GRAVITY_M_S2
from imuhal.core.frames import quat_to_matrix
from imuhal.core.samples import AccelSample, Frame, GyroSample, MagSample
from imuhal.estimation.outputs import AttitudeBlock, rows_of
from imuhal_filters.decoupled.core import DecoupledKernel
from imuhal_filters.decoupled.estimator import DecoupledEstimator, DecoupledSettings
from imuhal_filters.decoupled.fast import decoupled_sample
from imuhal_filters.decoupled.packed import covers, grown, pack, params_array, unpack

BACKENDS = pytest.mark.parametrize(
    "compiled_backend", ["aot", pytest.param("jit", marks=pytest.mark.long)], indirect=True)
"""The AOT extension (built once per session for every compiled test) by default; numba's
JIT on demand (``-m long``): compiling the decoupled kernels on it costs about 20 s of CPU
per process (docs/performance.md), which the default suite does not pay."""

STILL_S = 3.0
MAG_PULLED = (7.0, 9.0)
ACCEL_GAP = (8.5, 8.9)
"""No accelerometer reading (s): inside the turn's look-back episode."""


@dataclass(frozen=True)
class Case:
    gyro: np.ndarray
    acc_g: np.ndarray
    mag: np.ndarray
    dts: np.ndarray
    accel_read: np.ndarray
    """False: no accelerometer reading at that step (``ACCEL_GAP``)."""


@cache
def _case() -> Case:
    m = flight(10.0, turn_deg_s=20.0, seed=4)
    rate = 100.0
    n_still = round(STILL_S * rate)
    rng = np.random.default_rng(11)
    gyro = np.vstack([rng.normal(0.004, 0.002, (n_still, 3)), m.gyro_rad_s])
    acc = np.vstack([np.tile(m.accel_m_s2[0], (n_still, 1)) + rng.normal(0, 0.02, (n_still, 3)),
                     m.accel_m_s2])
    field = np.array([quat_to_matrix(q).T @ FIELD_NED_UT for q in m.q_true])
    mag = np.vstack([np.tile(field[0], (n_still, 1)), field])
    t = np.arange(len(gyro)) / rate
    # a hand's stroke before the flight: pushed, then braked back to rest
    acc[(t >= 0.8) & (t < 1.3), 0] += 3.0
    acc[(t >= 1.3) & (t < 1.8), 0] -= 3.0
    pulled = (t >= MAG_PULLED[0]) & (t < MAG_PULLED[1])
    mag[pulled] += (30.0, -20.0, 10.0)
    dts = np.full(len(gyro), 1.0 / rate)
    dts[::37] = 0.013
    read = (t < ACCEL_GAP[0]) | (t >= ACCEL_GAP[1])
    return Case(gyro, -acc / STANDARD_GRAVITY_M_S2, mag, dts, read)


def _params() -> DecoupledSettings:
    return DecoupledSettings(sample_period_s=0.01)


def _python_run(case: Case) -> Iterator[tuple[np.ndarray, DecoupledKernel]]:
    k = DecoupledKernel(_params().params())
    k.start((1.0, 0.0, 0.0, 0.0))
    for g, a, mg, dt, read in zip(case.gyro.tolist(), case.acc_g.tolist(), case.mag.tolist(),
                                  case.dts.tolist(), case.accel_read.tolist(), strict=True):
        q = k.step(tuple(g), tuple(a) if read else None, tuple(mg), dt)
        yield np.array(q), k


def test_the_case_meets_rest_episodes_readmission_a_disturbed_field_and_a_gap() -> None:
    rest = episodes = disturbed = 0
    readmitted = 0
    missed = False
    episode_at_gap = gap_ends_it = False
    for _, k in _python_run(_case()):
        rest += k.rest
        assert k.lookback is not None
        if k.accel_missed and not missed:  # the gap's first step
            episode_at_gap = k.lookback.episode_s is not None
        if missed and not k.accel_missed:  # the first reading after it
            gap_ends_it = k.lookback.episode_s is None
        missed = k.accel_missed
        episodes += k.lookback.episode_s is not None
        disturbed += k.mag_disturbed
        readmitted = k.lookback.readmitted
    assert rest > 50 and episodes > 50 and disturbed > 50 and readmitted >= 1
    assert episode_at_gap and gap_ends_it
    assert covers(_params().params())


@BACKENDS
def test_compiled_step_gives_the_python_floats(compiled_backend: str) -> None:
    case = _case()
    p = _params().params()
    k = DecoupledKernel(p)
    k.start((1.0, 0.0, 0.0, 0.0))
    s, look = pack(k, rows=8)  # a small ring: it must grow on the way
    params = params_array(p)
    ref = _python_run(case)
    for i in range(len(case.dts)):
        if s[-1] + 2.0 > look.shape[0]:
            look = grown(s, look)
        g, a, mg = case.gyro[i], case.acc_g[i], case.mag[i]
        read = bool(case.accel_read[i])
        out = decoupled_sample(s, params, look, *map(float, g), read, *map(float, a), True,
                               *map(float, mg), float(case.dts[i]), 0.0, 0.0, 0.0)
        q_ref, k_ref = next(ref)
        assert np.array_equal(np.array(out[:4]), q_ref), i
        assert out[7] == k_ref.rest and out[8] == k_ref.mag_disturbed, i
    assert look.shape[0] > 8
    unpack(s, look, k)
    assert repr(_state(k)) == repr(_state(k_ref))


def _state(k: DecoupledKernel) -> dict:
    est = DecoupledEstimator({"sample_period_s": 0.01})
    est._kernel = k
    est._sample_kernel = None
    return est._filter_state()


def _estimates(case: Case, compiled: bool) -> list[str]:
    """Every estimate of the case through ``process()`` (the pipeline's path), by ``repr``,
    and the saved state at the end (``compiled``: on the compiled step, checked)."""
    est = DecoupledEstimator({"sample_period_s": 0.01})
    assert (est._sample_kernel is not None) == compiled
    t = 0
    out: list[str] = []
    for g, a, mg, dt, read in zip(case.gyro.tolist(), case.acc_g.tolist(), case.mag.tolist(),
                                  case.dts.tolist(), case.accel_read.tolist(), strict=True):
        t += round(dt * 1e9)
        f = tuple(-c * STANDARD_GRAVITY_M_S2 for c in a)
        samples: list[AccelSample | MagSample | GyroSample] = [
            MagSample(t_ns=t, device="mag", frame=Frame.BODY_NED, mag_ut=tuple(mg)),
            GyroSample(t_ns=t, device="imu", frame=Frame.BODY_NED, gyro_rad_s=tuple(g))]
        if read:  # the gap: the estimator holds the last reading max_aux_age_s, then none
            samples.insert(0, AccelSample(t_ns=t, device="imu", frame=Frame.BODY_NED,
                                          accel_m_s2=f))
        for s in samples:
            out += [repr(e) for e in est.process(s)]
    out.append(repr(est.get_state()))
    return out


@BACKENDS
def test_the_estimator_on_the_compiled_step_gives_the_python_estimates(
        compiled_backend: str, monkeypatch: pytest.MonkeyPatch) -> None:
    case = _case()
    compiled = _estimates(case, True)
    monkeypatch.setenv("IMUHAL_KERNELS", "python")
    assert compiled == _estimates(case, False)


@BACKENDS
def test_the_offline_passes_give_the_python_floats(
        compiled_backend: str, monkeypatch: pytest.MonkeyPatch) -> None:
    case = _case()
    est = DecoupledEstimator({"sample_period_s": 0.01, "offline": True})
    acc = -case.acc_g * STANDARD_GRAVITY_M_S2
    compiled = est.smooth(case.gyro, acc, case.mag)
    monkeypatch.setenv("IMUHAL_KERNELS", "python")
    assert np.array_equal(compiled, est.smooth(case.gyro, acc, case.mag))


DECOUPLED_FIFO_CASES: list[tuple[dict[str, Any], str]] = [
    ({}, "in"),
    ({}, "apart"),
    ({"nominal_airspeed_m_s": 10.0}, "apart"),
    ({"use_mag": False, "dt_from_timestamps": False}, "in"),
]


@BACKENDS
@pytest.mark.parametrize(("settings", "with_mag"), DECOUPLED_FIFO_CASES,
                         ids=[f"{','.join(map(str, s.values())) or 'defaults'}-mag-{m}"
                              for s, m in DECOUPLED_FIFO_CASES])
def test_fifo_reads_through_the_block_step_give_the_frames_one_by_one(
        settings: dict, with_mag: str, compiled_backend: str) -> None:
    """The block step (``decoupled_block``) on FIFO reads of 8 frames with the awkward
    frames of tests/filters/test_ahrs_blocks.py (clipped values, stale held frames, a time
    jump, a repeated time stamp: those reads go frame by frame): the estimates of
    ``process()`` by ``repr``, as AttitudeBlocks from ``estimate_blocks`` too, the same
    saved state; and it took most reads."""
    est, ref = _pair("decoupled", settings)
    by_block, _ = _pair("decoupled", settings)
    assert est._has_block_step()
    reads = _fifo_reads(8, with_mag)
    got: list[Any] = []
    blocks: list[Any] = []
    for read in reads:
        got += est.update_blocks(read)
        blocks += by_block.estimate_blocks(read)
    want = [repr(e) for e in _frame_by_frame(ref, reads)]
    assert [repr(e) for e in got] == want
    assert [repr(e) for e in rows_of(blocks)] == want
    assert repr(est.get_state()) == repr(ref.get_state()) == repr(by_block.get_state())
    imu_reads = sum(1 for read in reads if len(read) > 1)
    assert sum(len(b) for b in blocks if isinstance(b, AttitudeBlock)) > 8 * imu_reads // 2
