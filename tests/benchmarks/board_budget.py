"""Where the emulated seed board's CPU goes, by making parts of it free (plain script; not
collected by pytest). An experiment, not the same floats: each variant changes what runs.

Run:  .venv/bin/python -m tests.benchmarks.board_budget [--duration 60] [--repeat 2]

Variants (each a fresh pipeline on ``thermal``, x real time by CPU):

* ``as is``: the seed board with its estimators and every chip's error model;
* ``no estimators``: the profile's estimators removed;
* ``no magnetometer``: the HMC5883L behind the MAX21100's I2C master removed (the AHRS then
  runs on the IMU alone);
* ``truth free``: every chip gets one fixed truth, the scenario's at 1 s (still on launch,
  so the start-up gyro offsets are measured as in the real run; the error models still run,
  so the words keep changing and no chip looks frozen): the scenario costs nothing;
* and the combinations ``truth free, no estimators`` and ``truth free, no magnetometer``.

The budget of a part is ``1/x(as is) - 1/x(without it)`` seconds of CPU per simulated
second (docs/performance.md, "Why 40 x and 60 us are not reached").
"""

from __future__ import annotations

import argparse
import os
import statistics
import time
from pathlib import Path
from typing import Any

import yaml

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")

from imuhal.emulation import open_emulated
from imuhal.emulation.board import EmulatedBoard
from imuhal.plugins.manager import Registry, load_registry
from imuhal.profile.loader import load_profile
from imuhal.profile.model import BoardProfile

PROFILE = Path(__file__).resolve().parents[2] / "profiles" / "seed-paraglider-vario.yaml"
VARIANTS = ("as is", "no estimators", "no magnetometer", "truth free",
            "truth free, no estimators", "truth free, no magnetometer")


def _profile(registry: Registry, variant: str, tmp: Path) -> BoardProfile:
    doc: dict[str, Any] = yaml.safe_load(PROFILE.read_text())
    if "no magnetometer" in variant:
        del doc["devices"]["mag"]
        doc["estimators"]["ahrs"]["inputs"] = ["imu"]
    if "no estimators" in variant:
        doc["estimators"] = {}
    path = tmp / f"{variant.replace(' ', '_').replace(',', '')}.yaml"
    path.write_text(yaml.safe_dump(doc))
    return load_profile(path, registry)


def x_real_time(registry: Registry, variant: str, duration_s: float, tmp: Path
                ) -> tuple[float, int]:
    """(simulated s per CPU s, warnings the run raised) of one run of ``variant``."""
    pipeline = open_emulated(_profile(registry, variant, tmp), registry, scenario="thermal")
    if "truth free" in variant:
        board = EmulatedBoard.of(pipeline)
        fixed = {True: board.scenario.chip_truth(1.0),
                 False: board.scenario.chip_truth(1.0, motion=False)}
        board._chip_truth = lambda t_ns, motion: fixed[motion]  # type: ignore[method-assign]
    with pipeline:
        t0 = time.process_time()
        for _ in pipeline.events(duration_s):
            pass
        cpu = time.process_time() - t0
    return duration_s / cpu, len(pipeline.warnings)


def main(argv: list[str] | None = None) -> int:
    import tempfile

    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--duration", type=float, default=60.0, help="simulated s (default 60)")
    p.add_argument("--repeat", type=int, default=2, help="runs of each variant, interleaved")
    args = p.parse_args(argv)
    registry = load_registry()
    runs: dict[str, list[float]] = {v: [] for v in VARIANTS}
    warned: dict[str, int] = dict.fromkeys(VARIANTS, 0)
    with tempfile.TemporaryDirectory() as tmp:
        for _ in range(args.repeat):
            for variant in VARIANTS:
                x, w = x_real_time(registry, variant, args.duration, Path(tmp))
                runs[variant].append(x)
                warned[variant] += w
    base = statistics.median(runs["as is"])
    print(f"| seed board, {args.duration:g} s | x real time (median of {args.repeat}) "
          "| CPU ms per simulated s | saved against as is |")
    print("| --- | ---: | ---: | ---: |")
    for variant in VARIANTS:
        x = statistics.median(runs[variant])
        saved = "" if variant == "as is" else f"{1000 / base - 1000 / x:.1f}"
        note = f" ({warned[variant]} warnings)" if warned[variant] else ""
        print(f"| {variant}{note} | {x:.1f} | {1000 / x:.1f} | {saved} |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
