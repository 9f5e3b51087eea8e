"""Simulator cost per sensor sample (pytest-benchmark; not part of the default run).

Run:  .venv/bin/pytest tests/benchmarks/bench_sim.py --benchmark-only -q

Each case is timed next to a peer measured in the same run (a bare numpy rotation of one
vector per call, the cheapest thing a per-sample simulator could possibly do), and the
ratio is stored in ``extra_info`` and printed, so results compare across machines.
"""

from __future__ import annotations

import timeit

import numpy as np
import pytest

from imuhal.core.frames import quat_from_euler_deg, quat_to_matrix
from imuhal.sim.errors import SensorErrorModel, error_spec_of
from imuhal.sim.rc_flight import RcFlightScenario
from imuhal.sim.thermal import ThermalScenario
from imuhal.sim.world import physical_inputs
from imuhal_chips.mpu9250.emulator import MPU9250Emulator

PERIOD = 0.005


def _peer_seconds_per_call() -> float:
    q = quat_from_euler_deg(10.0, 5.0, 30.0)
    v = np.array([0.0, 0.0, -9.80665])
    n = 20_000
    return min(timeit.repeat(lambda: quat_to_matrix(q).T @ v, number=n, repeat=5)) / n


def _report(benchmark, label: str) -> None:
    peer = _peer_seconds_per_call()
    mean = benchmark.stats.stats.mean
    benchmark.extra_info["peer_numpy_rotation_us"] = peer * 1e6
    benchmark.extra_info["ratio_vs_peer"] = mean / peer
    print(f"\n{label}: {mean * 1e6:.1f} us per sample, {mean / peer:.1f}x a bare numpy "
          f"rotation ({peer * 1e6:.2f} us)")


@pytest.mark.parametrize("cls", [ThermalScenario, RcFlightScenario], ids=["thermal", "rc-flight"])
def test_truth_per_sample(benchmark, cls):
    scenario = cls(seed=0)
    clock = iter(np.arange(0.0, 1e6, PERIOD).tolist())
    scenario.truth(scenario.duration_s)        # position table filled once, as in a run
    benchmark(lambda: scenario.truth(next(clock) % scenario.duration_s))
    _report(benchmark, f"{cls.name} truth")


def test_truth_plus_imu_error_model_per_sample(benchmark):
    scenario = ThermalScenario(seed=0)
    model = SensorErrorModel(error_spec_of(MPU9250Emulator), seed=0)
    clock = iter(np.arange(0.0, 1e6, PERIOD).tolist())
    scenario.truth(scenario.duration_s)

    def sample():
        t = next(clock)
        truth = scenario.truth(t % scenario.duration_s)
        return model.apply(t, physical_inputs(truth, mag=False, pressure=False), PERIOD)

    benchmark(sample)
    _report(benchmark, "thermal truth + mpu9250 errors")


def test_numpy_rotation_peer(benchmark):
    q = quat_from_euler_deg(10.0, 5.0, 30.0)
    v = np.array([0.0, 0.0, -9.80665])
    benchmark(lambda: quat_to_matrix(q).T @ v)
    _report(benchmark, "peer itself")
