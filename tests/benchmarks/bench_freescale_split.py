"""The Freescale kernel as helper kernels against the one-function kernel it was split from
(issue 29 item 4), on numba's JIT, in the same process (plain script; not collected by
pytest).

Run:  nice .venv/bin/python -m tests.benchmarks.bench_freescale_split [--rev REV]
          [--samples N] [--rounds R]

Three kernels: ``plugins/imuhal_filters/freescale/fast.py`` as it was at ``REV`` (default
1b0b761^, the commit before the split: one function), read with ``git show`` and imported as
a module of its own; the working tree's with its helper kernels called (its
``inline_kernel`` marks removed); and the working tree's as it runs (helpers inlined into
the kernel by numba). All run the same ``run_9dof``/``run_6dof`` calls (default settings;
bench_all's gently moving board, N samples at 250 Hz): ``batch.freescale_rows`` is swapped
for the kernel under test, and only the kernel's calls are timed (CPU time; the Python steps
before the filter locks are the same for all). Each round runs the three in turn, so that
load drifts hit them alike; the ratios are of the medians (in brackets: the range of the
rounds' inlined / one-function ratios). The three kernels' outputs must be bit for bit the
same, or the script fails.
"""

from __future__ import annotations

import argparse
import importlib
import os
import re
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


def kernel_from(source: str, name: str, directory: Path) -> Any:
    """The ``freescale_rows`` kernel of ``source``, imported from ``directory`` as the
    module ``name``."""
    (directory / f"{name}.py").write_text(source, encoding="utf-8")
    if str(directory) not in sys.path:
        sys.path.insert(0, str(directory))
    return importlib.import_module(name).freescale_rows


def kernels(rev: str, directory: Path) -> dict[str, Any]:
    """The kernels compared: ``KERNEL_FILE`` at ``rev`` (one function), the working tree's
    with its helpers called (not inlined), and the working tree's as it runs."""
    old = subprocess.run(["git", "show", f"{rev}:{KERNEL_FILE}"], cwd=ROOT, check=True,
                         capture_output=True, text=True).stdout
    now = (ROOT / KERNEL_FILE).read_text(encoding="utf-8")
    called = re.sub(r"inline_kernel\((jit\(\w+\))\)", r"\1", now)
    return {"one function": kernel_from(old, "freescale_fast_at_rev", directory),
            "split, helpers called": kernel_from(called, "freescale_fast_called", directory),
            "split, helpers inlined": batch.freescale_rows}


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
    with tempfile.TemporaryDirectory() as tmp:
        compared = kernels(args.rev, Path(tmp))
        print(f"{args.samples} samples at 250 Hz, {args.rounds} rounds, JIT, CPU us per "
              f"Kalman window (median); one function: {KERNEL_FILE} at {args.rev}")
        print("| case | " + " | ".join(compared) + " | called / one function | "
              "inlined / one function (rounds) |")
        print("|---|" + "---:|" * (len(compared) + 2))
        for name, (settings, case) in cases.items():
            windows = args.samples // settings.oversample_ratio
            outputs = [run(k, case)[1] for k in compared.values()]  # compiles, outside timing
            if not all(same(outputs[0], o) for o in outputs[1:]):
                print(f"{name}: the kernels' outputs differ", file=sys.stderr)
                return 1
            times: dict[str, list[float]] = {k: [] for k in compared}
            for _ in range(args.rounds):
                for label, kernel in compared.items():
                    times[label].append(run(kernel, case)[0])
            med = {k: statistics.median(v) for k, v in times.items()}
            one, called, inlined = (med[k] for k in compared)
            ratios = [n / o for o, n in zip(times["one function"],
                                            times["split, helpers inlined"], strict=True)]
            print(f"| {name} | " + " | ".join(f"{1e6 * m / windows:.3f}" for m in med.values())
                  + f" | {called / one:.3f} | {inlined / one:.3f} "
                  f"({min(ratios):.3f}-{max(ratios):.3f}) |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
