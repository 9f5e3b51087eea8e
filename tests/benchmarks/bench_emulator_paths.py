"""The MAX2110x emulator's fast paths against its general paths, in one process (plain
script; not collected by pytest).

Run:  .venv/bin/python -m tests.benchmarks.bench_emulator_paths [--duration 20] [--repeat 4]

The seed paraglider vario (profiles/seed-paraglider-vario.yaml, ``thermal``, its estimators)
emulated with one frame per block and with its MAX21100 read from the FIFO in blocks of 8
frames, each with the emulator's fast paths (``Max2110xEmulator.fast_paths``: a FIFO fill's
planned measurements latched at once, both channels caught up as a pair) and with its
general paths (the tests' reference; the same events bit for bit), alternating, the best
of ``--repeat`` runs of each, in x real time by CPU and ms of CPU per simulated second. One
process and the same sources for both, so the difference is the fast paths' alone, less
disturbed by other jobs than two trees compared one after the other.
"""

from __future__ import annotations

import argparse
import os
import time

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

from tests.benchmarks.bench_blocks import SEED, board_yaml

from imuhal.emulation import open_emulated
from imuhal.emulation.board import EmulatedBoard
from imuhal.plugins.manager import Registry, load_registry
from imuhal.profile.loader import parse_profile


def cpu_s(registry: Registry, profile_yaml: str, duration_s: float, fast: bool) -> float:
    """CPU seconds of one emulated flight of ``duration_s`` (start-up excluded)."""
    profile = parse_profile(profile_yaml, str(SEED), registry)
    with open_emulated(profile, registry, scenario="thermal") as pipeline:
        imu = EmulatedBoard.of(pipeline).emulators["imu"]
        imu.fast_paths = fast  # type: ignore[attr-defined]  # the seed board's MAX21100
        t0 = time.process_time()
        for _ in pipeline.events(duration_s):
            pass
        return time.process_time() - t0


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--duration", type=float, default=20.0, help="simulated s per run")
    p.add_argument("--repeat", type=int, default=4, help="runs of each case")
    args = p.parse_args(argv)
    registry = load_registry()
    modes = {"one frame per block": board_yaml(None, SEED),
             "FIFO blocks of 8": board_yaml(8, SEED)}
    best: dict[tuple[str, bool], float] = {}
    for _ in range(args.repeat):
        for mode, text in modes.items():
            for fast in (True, False):
                cpu = cpu_s(registry, text, args.duration, fast)
                best[mode, fast] = min(best.get((mode, fast), cpu), cpu)
    load = os.getloadavg()[0]
    for mode in modes:
        fast, general = best[mode, True], best[mode, False]
        print(f"seed board, {mode}: fast paths {args.duration / fast:.1f} x real time "
              f"({1e3 * fast / args.duration:.1f} ms cpu per s), general paths "
              f"{args.duration / general:.1f} x ({1e3 * general / args.duration:.1f} ms); "
              f"fast / general {fast / general:.3f} (best of {args.repeat} x "
              f"{args.duration:g} s, load {load:.1f})")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
