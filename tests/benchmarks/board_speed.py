"""The seed board's speed alone, best of several runs (plain script; not collected by pytest).

Run:  .venv/bin/python -m tests.benchmarks.board_speed [--duration 20] [--repeat 5]

The seed paraglider vario (profiles/seed-paraglider-vario.yaml, ``thermal``, its
estimators) emulated with one frame per block and with its MAX21100 read from the FIFO in
blocks of 8 frames, in x real time by CPU, the best of ``--repeat`` runs of each,
alternating. Meant for comparing two trees in the same minutes on a shared machine (run it
from each, one after the other, with ``PYTHONPATH`` at the other tree's ``src`` and
``plugins``): the best of several short runs is less disturbed by other jobs than one long
run. ``bench_all`` gives the same figure beside its peers.
"""

from __future__ import annotations

import argparse
import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

from tests.benchmarks.bench_blocks import SEED, board_x_real_time, board_yaml

from imuhal.plugins.manager import load_registry


def best_x_real_time(duration_s: float, repeat: int) -> dict[str, float]:
    """{mode: best x real time} for one frame per block and FIFO blocks of 8."""
    registry = load_registry()
    modes = {"one frame per block": board_yaml(None, SEED),
             "FIFO blocks of 8": board_yaml(8, SEED)}
    best = dict.fromkeys(modes, 0.0)
    for _ in range(repeat):
        for mode, text in modes.items():
            best[mode] = max(best[mode], board_x_real_time(registry, text, duration_s, SEED))
    return best


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--duration", type=float, default=20.0, help="simulated s per run")
    p.add_argument("--repeat", type=int, default=5, help="runs of each mode")
    args = p.parse_args(argv)
    for mode, x in best_x_real_time(args.duration, args.repeat).items():
        print(f"seed board, {mode}: {x:.1f} x real time (cpu), best of {args.repeat} "
              f"x {args.duration:g} s")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
