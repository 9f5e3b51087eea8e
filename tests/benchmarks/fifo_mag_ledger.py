"""The seed paraglider's magnetometer ledger when its MAX21100 is read from the FIFO (plain
script; not collected by pytest).

Run:  .venv/bin/python -m tests.benchmarks.fifo_mag_ledger [--duration 20] [--frames 1,2,3,4,8]

The bundled seed-paraglider-vario with its MAX21100 set to ``read: fifo`` and each
``fifo_frames`` given, flying ``thermal`` (seed 1, the profile's sensor errors, no faults):
the HMC5883L behind the MAX21100's auto-read delivers its copies only with the FIFO reads,
so with reads further apart its fields are stamped and counted from copies up to
``fifo_frames`` periods late. Prints, per ``fifo_frames``, the magnetometer's frame ledger
(produced, delivered, lost) beside the measurements the emulated chip made over the
ledger's segments (``ChipEmulator.frames_between``): the fault matrix's check, which flies
the bundled profiles (register reads) only.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

from tests.benchmarks.bench_blocks import SEED, board_yaml
from tests.benchmarks.fault_matrix import ledgers_of

from imuhal.emulation import open_emulated
from imuhal.plugins.manager import load_registry
from imuhal.profile.loader import load_profile


def mag_ledger(fifo_frames: int, duration_s: float) -> dict[str, int]:
    """The magnetometer's ledger counts and the chip's measurements over its segments
    (``chip``), as the fault matrix compares them (``ledgers_of``)."""
    registry = load_registry()
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "board.yaml"
        path.write_text(board_yaml(fifo_frames, SEED))
        profile = load_profile(path, registry)
    with open_emulated(profile, registry, seed=1, scenario="thermal") as pipeline:
        for _ in pipeline.events(duration_s):
            pass
        return ledgers_of(pipeline)["mag"]


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--duration", type=float, default=20.0, help="simulated s per run")
    p.add_argument("--frames", default="1,2,3,4,8", help="comma-separated fifo_frames")
    args = p.parse_args(argv)
    print(f"seed-paraglider-vario, read: fifo, thermal {args.duration:g} s, seed 1: the "
          "magnetometer's ledger against the chip's measurements\n")
    print("| fifo_frames | produced (ledger) | delivered | lost (ledger) | the chip's count "
          "| ledger - chip |")
    print("| ---: | ---: | ---: | ---: | ---: | ---: |")
    for n in (int(x) for x in args.frames.split(",")):
        counts = mag_ledger(n, args.duration)
        measured = counts["chip"]
        lost = counts["produced"] - counts["delivered"]
        print(f"| {n} | {counts['produced']} | {counts['delivered']} | {lost} | {measured} "
              f"| {counts['produced'] - measured:+d} |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
