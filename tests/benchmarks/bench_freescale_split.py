"""The Freescale kernel as helper kernels against the one-function kernel it was split from
(issue 29 item 4), on numba's JIT, in the same process (plain script; not collected by
pytest).

Run:  nice .venv/bin/python -m tests.benchmarks.bench_freescale_split [--rev REV]
          [--samples N] [--rounds R]

The one-function kernel is ``plugins/imuhal_filters/freescale/fast.py`` as it was at ``REV``
(default 1b0b761^, the commit before the split), read with ``git show`` and imported as a
module of its own; the split kernel is the working tree's. Both run the same
``run_9dof``/``run_6dof`` calls (default settings; bench_all's gently moving board, N samples
at 250 Hz): ``batch.freescale_rows`` is swapped for the kernel under test, and only the
kernel's calls are timed (CPU time; the Python steps before the filter locks are the same
for both). The rounds alternate old and new so that load drifts hit both alike; the ratio is
of the medians. The outputs must be bit for bit the same, or the script fails.
"""

from __future__ import annotations

import argparse
import importlib
import os
import statistics
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ["IMUHAL_KERNELS"] = "jit"

import numpy as np
from tests.benchmarks.bench_all import motion

from imuhal_filters.freescale import batch
from imuhal_filters.freescale.settings import (
    Freescale6DofSettings,
    Freescale9DofSettings,
)

ROOT = Path(__file__).resolve().parents[2]
KERNEL_FILE = "plugins/imuhal_filters/freescale/fast.py"


class TimedKernel:
    """A kernel whose calls add up their CPU seconds."""

    def __init__(self, kernel: Any) -> None:
        self.kernel = kernel
        self.seconds = 0.0

    def available(self) -> bool:
        return bool(self.kernel.available())

    def __call__(self, *args: Any) -> None:
        t0 = time.process_time()
        self.kernel(*args)
        self.seconds += time.process_time() - t0


def kernel_at(rev: str, directory: Path) -> Any:
    """The ``freescale_rows`` kernel of ``KERNEL_FILE`` at ``rev``, imported from
    ``directory`` as the module ``freescale_fast_at_rev``."""
    source = subprocess.run(["git", "show", f"{rev}:{KERNEL_FILE}"], cwd=ROOT, check=True,
                            capture_output=True, text=True).stdout
    (directory / "freescale_fast_at_rev.py").write_text(source, encoding="utf-8")
    sys.path.insert(0, str(directory))
    return importlib.import_module("freescale_fast_at_rev").freescale_rows


def run(kernel: Any, case: Callable[[], Any]) -> tuple[float, Any]:
    """CPU seconds in ``kernel`` during ``case()``, and what ``case()`` returned."""
    timed = TimedKernel(kernel)
    saved, batch.freescale_rows = batch.freescale_rows, timed
    try:
        result = case()
    finally:
        batch.freescale_rows = saved
    return timed.seconds, result


def same(a: Any, b: Any) -> bool:
    fields = ("q_sensor_to_global", "gyro_offset_dps", "inclination_deg", "mag_jamming",
              "euler_deg", "row")
    return all(np.array_equal(getattr(a, f), getattr(b, f)) for f in fields)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--rev", default="1b0b761^")
    parser.add_argument("--samples", type=int, default=200_000)
    parser.add_argument("--rounds", type=int, default=9)
    args = parser.parse_args(argv)
    gyro, accel, mag = motion(args.samples)
    ag, gd = -accel / 9.80665, np.degrees(gyro)
    s9, s6 = Freescale9DofSettings(), Freescale6DofSettings()
    cases = {"run_9dof": (s9, lambda: batch.run_9dof(ag, gd, mag, s9)),
             "run_6dof": (s6, lambda: batch.run_6dof(ag, gd, s6))}
    new = batch.freescale_rows
    with tempfile.TemporaryDirectory() as tmp:
        old = kernel_at(args.rev, Path(tmp))
        print(f"{args.samples} samples at 250 Hz, {args.rounds} rounds, JIT; split kernel "
              f"(working tree) against {KERNEL_FILE} at {args.rev}")
        print("| case | one function (us/window) | split (us/window) | split / one function "
              "| rounds' ratios |")
        print("|---|---:|---:|---:|---|")
        for name, (settings, case) in cases.items():
            windows = args.samples // settings.oversample_ratio
            _, reference = run(old, case)  # compile (or load the cache) outside the timing
            _, result = run(new, case)
            if not same(reference, result):
                print(f"{name}: the split kernel's outputs differ from {args.rev}'s",
                      file=sys.stderr)
                return 1
            times: dict[str, list[float]] = {"old": [], "new": []}
            for _ in range(args.rounds):
                times["old"].append(run(old, case)[0])
                times["new"].append(run(new, case)[0])
            ratios = [n / o for o, n in zip(times["old"], times["new"], strict=True)]
            o, n = statistics.median(times["old"]), statistics.median(times["new"])
            print(f"| {name} | {1e6 * o / windows:.3f} | {1e6 * n / windows:.3f} | "
                  f"{n / o:.3f} | {min(ratios):.3f}-{max(ratios):.3f} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
