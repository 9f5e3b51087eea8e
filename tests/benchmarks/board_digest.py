"""A fingerprint of everything an emulated board run emits (plain script; not collected by pytest).

Run:  .venv/bin/python -m tests.benchmarks.board_digest [--duration 600] [--bare] [--every 0]

The seed paraglider vario board (profiles/seed-paraglider-vario.yaml) flies ``thermal`` for
``--duration`` simulated seconds with its estimators (``--bare``: none) and every chip's
error model; every emitted event (each sample and each estimate, diagnostics included) is
hashed through its ``repr``, which writes every float so that it round-trips bit for bit.
Two versions of the emulator, drivers or pipeline emit the same floats exactly when they
print the same digest and the same event count. Speed work on the emulated board is proven
with it: run it on the commit before the change and after (docs/performance.md).

``--faults`` injects a fixed set of faults through the documented interface
(imuhal.emulation.faults: bus errors on every device, a chip reset, stuck data-ready, a
wild value, late polls), so the recovery and retry paths are compared too.

``--fifo-frames N`` reads the MAX21100 from its FIFO in blocks of N frames (``read: fifo``,
as tests/benchmarks/bench_blocks.py does), so the block path is fingerprinted too.

``--profile NAME`` flies another bundled board (profiles/NAME.yaml: gy91, seed-gps-vario,
seed-rc-vario; their devices carry the same names, so ``--faults`` applies to them too).

``--every N`` also prints a running digest every N events, to find where two runs diverge.

The first of ``FAULTS`` starts at 20 s: a run of 20 s or less has none in force, and prints
the digest of the run without ``--faults`` (a warning says so).
"""

from __future__ import annotations

import argparse
import hashlib
import os
import sys
import time
from collections import Counter
from pathlib import Path

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")

from imuhal.emulation import open_emulated
from imuhal.emulation.faults import (
    BusErrors,
    ChipReset,
    FaultSpec,
    LatePolls,
    StuckDataReady,
    WildValue,
)
from imuhal.plugins.manager import load_registry
from imuhal.profile.loader import load_profile, parse_profile

PROFILES = Path(__file__).resolve().parents[2] / "profiles"
PROFILE = PROFILES / "seed-paraglider-vario.yaml"


FAULTS: tuple[FaultSpec, ...] = (
    BusErrors(device="imu", rate=0.01, start_s=20.0, end_s=80.0),
    BusErrors(device="mag", rate=0.02, start_s=30.0, end_s=90.0),
    BusErrors(device="baro", rate=0.02, start_s=40.0, end_s=100.0),
    ChipReset(device="mag", start_s=110.0),
    ChipReset(device="imu", start_s=130.0),
    StuckDataReady(device="imu", start_s=150.0, end_s=150.5),
    WildValue(device="imu", channel="gyro", axis=1, value=50.0, start_s=170.0),
    LatePolls(device="baro", delay_s=0.003, start_s=180.0, end_s=190.0),
)
"""The faults of ``--faults`` (simulated seconds)."""


def digest(duration_s: float, *, estimators: bool = True, scenario: str = "thermal",
           every: int = 0, faults: bool = False, fifo_frames: int | None = None,
           board: Path = PROFILE) -> tuple[str, Counter[str], float]:
    """(sha256 of every event's repr, events by type, CPU seconds of the run)."""
    registry = load_registry()
    if fifo_frames is None:
        profile = load_profile(board, registry)
    else:
        from tests.benchmarks.bench_blocks import board_yaml
        profile = parse_profile(board_yaml(fifo_frames, board), str(board), registry)
    if not estimators:
        profile = profile.model_copy(update={"estimators": {}})
    pipeline = open_emulated(profile, registry, scenario=scenario,
                             faults=FAULTS if faults else ())
    h = hashlib.sha256()
    counts: Counter[str] = Counter()
    n = 0
    with pipeline:
        t0 = time.process_time()
        for event in pipeline.events(duration_s):
            h.update(repr(event).encode())
            h.update(b"\n")
            counts[type(event).__name__] += 1
            n += 1
            if every and n % every == 0:
                print(f"  {n:>9d} events  t={event.t_ns / 1e9:10.4f} s  {h.hexdigest()[:16]}")
        cpu = time.process_time() - t0
    return h.hexdigest(), counts, cpu


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--duration", type=float, default=600.0, help="simulated s (default 600)")
    p.add_argument("--bare", action="store_true", help="the board without its estimators")
    p.add_argument("--scenario", default="thermal")
    p.add_argument("--faults", action="store_true", help="inject the fixed FAULTS")
    p.add_argument("--every", type=int, default=0, help="print a running digest every N events")
    p.add_argument("--fifo-frames", type=int, default=None,
                   help="read the IMU's FIFO in blocks of this many frames")
    p.add_argument("--profile", default=PROFILE.stem,
                   help=f"a bundled board (profiles/NAME.yaml; default {PROFILE.stem})")
    args = p.parse_args(argv)
    board = PROFILES / f"{args.profile}.yaml"
    if not board.is_file():
        p.error(f"--profile {args.profile}: no profiles/{args.profile}.yaml; bundled: "
                + ", ".join(sorted(f.stem for f in PROFILES.glob("*.yaml"))))
    first_fault_s = min(spec.start_s for spec in FAULTS)
    if args.faults and args.duration <= first_fault_s:
        print(f"warning: the first fault starts at {first_fault_s:g} s; a run of "
              f"{args.duration:g} s has none in force", file=sys.stderr)
    sha, counts, cpu = digest(args.duration, estimators=not args.bare,
                              scenario=args.scenario, every=args.every, faults=args.faults,
                              fifo_frames=args.fifo_frames, board=board)
    what = ("without estimators" if args.bare else "with its estimators") + \
        (", faults injected" if args.faults else "") + \
        ("" if args.fifo_frames is None else f", FIFO blocks of {args.fifo_frames}")
    by_type = ", ".join(f"{k} {v}" for k, v in sorted(counts.items()))
    print(f"{args.profile} {what}, {args.scenario}, {args.duration:g} s: "
          f"{sum(counts.values())} events ({by_type})")
    print(f"sha256 {sha}")
    print(f"cpu {cpu:.2f} s = {args.duration / cpu:.1f} x real time", file=sys.stderr)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
