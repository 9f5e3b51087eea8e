"""The scenario's chip truth one instant at a time against many in one numpy pass (plain
script; not collected by pytest).

Run:  .venv/bin/python -m tests.benchmarks.bench_truths [--scenario thermal] [--sizes 8 250]

For each batch size n, ``Scenario.chip_truths`` on n consecutive 250 Hz instants against
``Scenario.chip_truth`` at each of the same instants (the same floats:
tests/sim/test_chip_truths.py), in us of CPU per instant, over the same simulated span
after the position table it needs is filled. Why a chip with its own clock announces its
instants seconds ahead (``ChipEmulator.PULL_AHEAD_NS``) rather than per FIFO fill: numpy's
cost per call outweighs the per-instant work below a few dozen instants.
"""

from __future__ import annotations

import argparse
import os
import time

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

from imuhal.plugins.manager import load_registry

PERIOD_S = 0.004


def per_instant_us(scenario_name: str, n: int, instants: int) -> tuple[float, float]:
    """(chip_truths, chip_truth) in us of CPU per instant, over ``instants`` instants in
    batches of ``n``."""
    scenario = load_registry().scenarios.get(scenario_name)(None, seed=0)
    batches = max(1, instants // n)
    times = [[(b * n + i) * PERIOD_S for i in range(n)] for b in range(batches)]
    for batch in times:  # fill the trajectory's position table outside the timing
        scenario.chip_truth(batch[-1])
    t0 = time.process_time()
    for batch in times:
        scenario.chip_truths(batch)
    many = time.process_time() - t0
    t0 = time.process_time()
    for batch in times:
        for t in batch:
            scenario.chip_truth(t)
    one = time.process_time() - t0
    total = batches * n
    return many / total * 1e6, one / total * 1e6


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--scenario", default="thermal")
    p.add_argument("--sizes", type=int, nargs="+", default=[8, 50, 250, 1000])
    p.add_argument("--instants", type=int, default=10_000,
                   help="instants per size (40 s at 250 Hz; the table keeps 4 segments)")
    args = p.parse_args(argv)
    print(f"{args.scenario}, load average {os.getloadavg()[0]:.1f}")
    for n in args.sizes:
        many, one = per_instant_us(args.scenario, n, args.instants)
        print(f"n = {n:5d}: chip_truths {many:6.1f} us per instant, chip_truth {one:6.1f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
