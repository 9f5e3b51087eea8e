"""Speed of an emulated run of the seed board (plain script; not collected by pytest).

Run:  .venv/bin/python tests/benchmarks/bench_pipeline.py [--duration 600] [--require 20]

The seed paraglider vario board (profiles/seed-paraglider-vario.yaml: MAX21100 on SPI with
the HMC5883L behind its I2C master, MS5611 on SPI), every chip emulated at register level,
flies the ``thermal`` scenario for ``--duration`` simulated seconds (default 10 minutes) on
one core. Each case reports its speed as a multiple of real time, by wall clock and by
process CPU time (the CPU figure does not suffer when other jobs share the machine), and as
a multiple of a peer measured in the same run: a bare loop evaluating the scenario's truth
at 250 Hz over the same simulated time (what the IMU alone needs from the simulator, with
no error model, no emulator, no bus and no driver), so the ratio compares across machines.

Cases:

* ``board``: the seed board with every chip's datasheet error model, no estimators (what
  issue 4's 20x requirement is about);
* ``board, ideal chips``: the same with ``sensor_errors=False``;
* ``board + estimators``: the profile as shipped (Madgwick, vario KF, baro-only vario).

``--require X`` exits 1 when the ``board`` case runs slower than X times real time (CPU).
``--repeat N`` runs every case N times and keeps the fastest run of each: on a shared or
virtual machine the speed of one run can wander by 20 %, and the fastest run is the one
least disturbed.
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

# Tiny matrices only: keep numpy's BLAS on the one core the benchmark measures.
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")

from imuhal.emulation import open_emulated
from imuhal.plugins.manager import Registry, load_registry
from imuhal.profile.loader import load_profile
from imuhal.profile.model import BoardProfile

PROFILE = Path(__file__).resolve().parents[2] / "profiles" / "seed-paraglider-vario.yaml"
SCENARIO = "thermal"
PEER_RATE_HZ = 250.0


@dataclass(frozen=True)
class Timing:
    label: str
    simulated_s: float
    events: int
    wall_s: float
    cpu_s: float

    @property
    def realtime_wall(self) -> float:
        return self.simulated_s / self.wall_s

    @property
    def realtime_cpu(self) -> float:
        return self.simulated_s / self.cpu_s


def _timed(label: str, simulated_s: float, body: Callable[[], int]) -> Timing:
    wall0, cpu0 = time.perf_counter(), time.process_time()
    events = body()
    return Timing(label, simulated_s, events, time.perf_counter() - wall0,
                  time.process_time() - cpu0)


def run_board(label: str, profile: BoardProfile, registry: Registry, duration_s: float,
              **open_kwargs: object) -> Timing:
    """Time ``pipeline.events(duration_s)`` (opening the pipeline is not timed)."""
    pipeline = open_emulated(profile, registry, scenario=SCENARIO, **open_kwargs)

    def body() -> int:
        n = 0
        for _ in pipeline.events(duration_s):
            n += 1
        return n

    with pipeline:
        return _timed(label, duration_s, body)


def run_truth_peer(registry: Registry, duration_s: float, seed: int) -> Timing:
    """The peer: the scenario's truth at ``PEER_RATE_HZ`` over ``duration_s``."""
    scenario = registry.scenarios.get(SCENARIO)(None, seed=seed)
    n = int(duration_s * PEER_RATE_HZ)

    def body() -> int:
        for k in range(n):
            scenario.truth(k / PEER_RATE_HZ)
        return n

    return _timed(f"peer: bare {SCENARIO} truth at {PEER_RATE_HZ:g} Hz", duration_s, body)


def _pin(cpu: int | None) -> str:
    """The run is single-threaded anyway; pinning only keeps the scheduler from moving it."""
    if cpu is None:
        return "one thread, not pinned"
    os.sched_setaffinity(0, {cpu})
    return f"one thread, pinned to CPU {cpu}"


def table(rows: list[Timing], peer: Timing) -> str:
    head = (f"{'case':<42} {'sim s':>6} {'events':>8} {'wall s':>7} {'x real (wall)':>13} "
            f"{'x real (cpu)':>12} {'cpu / peer':>10}")
    lines = [head, "-" * len(head)]
    for r in [*rows, peer]:
        lines.append(f"{r.label:<42} {r.simulated_s:>6.0f} {r.events:>8d} {r.wall_s:>7.2f} "
                     f"{r.realtime_wall:>13.1f} {r.realtime_cpu:>12.1f} "
                     f"{r.cpu_s / peer.cpu_s:>10.2f}")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--duration", type=float, default=600.0,
                        help="simulated seconds per case (default 600)")
    parser.add_argument("--require", type=float, default=None,
                        help="fail unless the 'board' case runs at least this many times "
                             "faster than real time (CPU time)")
    parser.add_argument("--cpu", type=int, default=None,
                        help="pin the process to this CPU (default: let the OS choose)")
    parser.add_argument("--repeat", type=int, default=1,
                        help="run each case this many times and keep the fastest (default 1)")
    parser.add_argument("--quick", action="store_true",
                        help="only the 'board' case and the peer")
    args = parser.parse_args(argv)

    pinning = _pin(args.cpu)
    registry = load_registry()
    shipped = load_profile(PROFILE, registry)
    bare = shipped.model_copy(update={"estimators": {}})
    seed = shipped.emulation.seed

    def fastest(run: Callable[[], Timing]) -> Timing:
        return min((run() for _ in range(max(1, args.repeat))), key=lambda r: r.cpu_s)

    rows = [fastest(lambda: run_board("board (error models, no estimators)", bare, registry,
                                      args.duration))]
    if not args.quick:
        rows.append(fastest(lambda: run_board("board, ideal chips (sensor_errors=False)", bare,
                                              registry, args.duration, sensor_errors=False)))
        rows.append(fastest(lambda: run_board("board + estimators (profile as shipped)",
                                              shipped, registry, args.duration)))
    peer = fastest(lambda: run_truth_peer(registry, args.duration, seed))

    print(f"seed board ({PROFILE.name}), scenario {SCENARIO!r}, seed {seed}, "
          f"Python {sys.version.split()[0]}, {pinning}, fastest of {max(1, args.repeat)}")
    print(table(rows, peer))
    board = rows[0]
    if args.require is not None and board.realtime_cpu < args.require:
        print(f"FAIL: the board ran {board.realtime_cpu:.1f}x real time, "
              f"below the required {args.require:g}x")
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
