"""Blocks against single readings: one board read one frame per poll and from its FIFO
(plain script; not collected by pytest; ``bench_all`` prints the same rows).

Run:  .venv/bin/python -m tests.benchmarks.bench_blocks [--duration 60] [--fifo-frames 10]

The GY-91 (profiles/gy91.yaml: MPU-9250 with its AK8963 and a BMP280, Madgwick feeding
vario-kf3) runs twice in the same process: as profiled (``read: registers``: one burst per
sample, blocks of one frame) and with the MPU-9250 read from its FIFO every
``--fifo-frames`` periods (``read: fifo``: blocks of that many frames). The MAX21100 of the
seed paraglider vario has no FIFO reader yet, so the FIFO rows are this board's.

Two figures per mode: the emulated board with its estimators, x real time by CPU time, and
the hardware path (tests/benchmarks/bench_hardware_path.py: a recording of the board's bus
traffic replayed through drivers, decoding, calibration, rotation and estimators, no
emulator), CPU us per IMU sample. Each FIFO row's peer is the registers row of the same run.
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import yaml

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")

from tests.benchmarks.bench_hardware_path import measure

from imuhal.emulation import open_emulated
from imuhal.plugins.manager import Registry, load_registry
from imuhal.profile.loader import parse_profile

GY91 = Path(__file__).resolve().parents[2] / "profiles" / "gy91.yaml"
SEED = Path(__file__).resolve().parents[2] / "profiles" / "seed-paraglider-vario.yaml"


def board_yaml(fifo_frames: int | None, board: Path = GY91) -> str:
    """A bundled board's profile as text, its IMU (device ``imu``: the GY-91's MPU-9250, the
    seed paraglider vario's MAX21100) read from the FIFO every ``fifo_frames`` periods
    (None: as profiled, one burst per sample)."""
    text = board.read_text()
    if fifo_frames is None:
        return text
    doc = yaml.safe_load(text)
    doc["devices"]["imu"].setdefault("settings", {}).update(
        {"read": "fifo", "fifo_frames": fifo_frames})
    return yaml.safe_dump(doc, sort_keys=False)


def gy91_yaml(fifo_frames: int | None) -> str:
    """:func:`board_yaml` of the GY-91."""
    return board_yaml(fifo_frames, GY91)


def board_x_real_time(registry: Registry, profile_yaml: str, duration_s: float,
                      board: Path = GY91) -> float:
    """The emulated board with its estimators: simulated s per CPU s."""
    profile = parse_profile(profile_yaml, str(board), registry)
    with open_emulated(profile, registry, scenario="thermal") as pipeline:
        t0 = time.process_time()
        for _ in pipeline.events(duration_s):
            pass
        return duration_s / (time.process_time() - t0)


@dataclass(frozen=True)
class BlockFigures:
    """One mode's figures."""

    label: str
    x_real_time: float
    us_per_imu_sample: float
    bare_us_per_imu_sample: float


def measure_mode(registry: Registry, fifo_frames: int | None, duration_s: float,
                 repeat: int, board: Path = GY91) -> BlockFigures:
    text = board_yaml(fifo_frames, board)
    label = "one frame per block (read: registers)" if fifo_frames is None else \
        f"blocks of {fifo_frames} frames (read: fifo)"
    x = max(board_x_real_time(registry, text, duration_s, board)
            for _ in range(max(1, repeat)))
    hw = measure(duration_s, repeat=repeat, registry=registry, profile_yaml=text)
    return BlockFigures(label, x, hw.us_per_imu_sample, hw.bare_us_per_imu_sample)


def measure_both(duration_s: float, fifo_frames: int, repeat: int = 3
                 ) -> tuple[BlockFigures, BlockFigures]:
    """(registers, FIFO) in one process, one after the other."""
    registry = load_registry()
    return (measure_mode(registry, None, duration_s, repeat),
            measure_mode(registry, fifo_frames, duration_s, repeat))


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--duration", type=float, default=60.0, help="simulated s per case")
    p.add_argument("--fifo-frames", type=int, default=10, help="frames per FIFO read")
    p.add_argument("--repeat", type=int, default=3, help="runs per case; the fastest counts")
    args = p.parse_args(argv)
    for f in measure_both(args.duration, args.fifo_frames, args.repeat):
        print(f"gy91, {f.label}: emulated {f.x_real_time:.1f} x real time (cpu); hardware "
              f"path {f.us_per_imu_sample:.1f} us per IMU sample "
              f"({f.bare_us_per_imu_sample:.1f} without the estimators)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
