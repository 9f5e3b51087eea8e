"""What the GY-91's AHRS costs: the bundled board with its `decoupled` (issue 27 item 3)
against the Madgwick (beta 0.1) it ran before, in the same process, alternating (plain
script; not collected by pytest).

Run:  nice -n 10 .venv/bin/python -m tests.benchmarks.bench_gy91_ahrs [--duration 10]
      [--rounds 2] [--kernel-dir DIR]

The figures of tests/benchmarks/bench_blocks.py (the emulated board with its estimators, x
real time by CPU time; the hardware path, CPU us per IMU sample, and the same without the
estimators), one frame per block and FIFO blocks of 10, for each AHRS in turn. The
difference of the two "hardware path" figures of a round is the AHRS's own cost per IMU
sample. The AOT extension is built from the sources first (``imuhal kernels build`` into a
temporary directory) and the board runs in ``auto`` mode, as a board's default, so
Madgwick and `decoupled` take their compiled per-sample steps; `decoupled` is also run with
``IMUHAL_KERNELS=python``: its Python step, what the board ran before its compiled one
(decoupled/fast.py), in the same minutes.
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
from pathlib import Path

import yaml
from tests.benchmarks.bench_all import build_kernels
from tests.benchmarks.bench_blocks import GY91, board_x_real_time, board_yaml
from tests.benchmarks.bench_hardware_path import measure

from imuhal.plugins.manager import load_registry

DECOUPLED: dict[str, object] = {"estimator": "decoupled", "inputs": ["imu", "mag"]}
AHRS: dict[str, tuple[dict[str, object], str]] = {
    "madgwick, beta 0.1 (before issue 27)": (
        {"estimator": "madgwick", "inputs": ["imu", "mag"], "settings": {"beta": 0.1}},
        "auto"),
    "decoupled, Python step": (DECOUPLED, "python"),
    "decoupled, compiled step (the profile's)": (DECOUPLED, "auto"),
}
"""Each AHRS with the kernel backend it runs on (``IMUHAL_KERNELS``)."""


def with_ahrs(fifo_frames: int | None, ahrs: dict[str, object]) -> str:
    """profiles/gy91.yaml (its IMU read as bench_blocks reads it) with ``ahrs``."""
    doc = yaml.safe_load(board_yaml(fifo_frames, GY91))
    doc["estimators"]["ahrs"] = ahrs
    return yaml.safe_dump(doc, sort_keys=False)


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--duration", type=float, default=10.0, help="simulated s per case")
    p.add_argument("--rounds", type=int, default=2, help="rounds of every case")
    p.add_argument("--kernel-dir", help="a kernel directory `imuhal kernels build` made from "
                   "these sources (default: build one first, about 4 min of CPU)")
    args = p.parse_args(argv)
    registry = load_registry()
    with tempfile.TemporaryDirectory() as tmp:
        if args.kernel_dir is None:
            error = build_kernels(Path(tmp))
            if error is not None:
                raise SystemExit(f"imuhal kernels build failed: {error}")
        os.environ["IMUHAL_KERNEL_DIR"] = args.kernel_dir or tmp
        print("| round | read | AHRS | emulated (x real time, cpu) | hardware path (us/IMU "
              "sample) | without the estimators |")
        print("|---|---|---|---:|---:|---:|")
        for r in range(args.rounds):
            for fifo in (None, 10):
                for name, (ahrs, backend) in AHRS.items():
                    os.environ["IMUHAL_KERNELS"] = backend
                    text = with_ahrs(fifo, ahrs)
                    x = board_x_real_time(registry, text, args.duration)
                    hw = measure(args.duration, repeat=2, registry=registry, profile_yaml=text)
                    read = "one frame per block" if fifo is None else f"FIFO blocks of {fifo}"
                    print(f"| {r + 1} | {read} | {name} | {x:.1f} | "
                          f"{hw.us_per_imu_sample:.1f} | {hw.bare_us_per_imu_sample:.1f} |",
                          flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
