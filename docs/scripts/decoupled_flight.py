"""The decoupled estimator's flight figures in docs/estimators.md (its own section).

Usage::

    .venv/bin/python docs/scripts/decoupled_flight.py [--duration S] [NAME:JSON ...]

Flies the flight benchmark's scenarios once (``flight_benchmark.py``: calibrated seed board,
seed 1) and prints, for each estimator and settings given (default: madgwick, decoupled and
decoupled ``preset: handheld``), the tilt RMS / max in degrees over t >= 5 s for ``thermal``
with the benchmark's four speed settings, ``rc-flight`` with defaults and the nominal
airspeed, and the seconds from an upside-down start to within 1 deg. ``NAME:JSON`` is a
registry name and its settings, e.g. ``'decoupled:{"tau_acc_s": 6}'``.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parent))

import flight_benchmark as fb

from imuhal.plugins.manager import load_registry

DEFAULT_RUNS = ('madgwick:{}', 'decoupled:{}', 'decoupled:{"preset": "handheld"}')
THERMAL: dict[str, tuple[dict[str, Any], bool]] = {
    "defaults": ({}, False), "nominal 10 m/s": (fb._NOMINAL, False),
    "GNSS": ({}, True), "GNSS + nominal": (fb._NOMINAL, True)}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--duration", type=float, default=60.0, metavar="S")
    parser.add_argument("runs", nargs="*", default=list(DEFAULT_RUNS))
    args = parser.parse_args(argv)
    reg = load_registry()
    profile = fb.calibrated_seed_profile(reg)
    thermal = fb.fly(profile, reg, "thermal", args.duration)
    rc = fb.fly(profile, reg, "rc-flight", min(args.duration, 60.0))
    upside = fb.fly(profile, reg, "static", 6.0, {"roll_deg": 180.0})
    gnss = thermal.with_gnss()
    board = {"sample_period_s": 0.004}

    def est(name: str, settings: dict[str, Any]) -> Any:
        return reg.estimators.get(name)({**board, **settings})

    print("| estimator | settings | " + " | ".join(f"thermal {k}" for k in THERMAL)
          + " | rc-flight defaults | rc-flight nominal | upside down to 1 deg (s) |")
    for run in args.runs:
        name, _, raw = run.partition(":")
        extra = json.loads(raw or "{}")
        cells = []
        for speed, vel in THERMAL.values():
            f = fb.tilt_figures(thermal, fb.run_ahrs(est(name, {**speed, **extra}),
                                                     gnss if vel else thermal.samples))
            cells.append(f"{f.rms_deg:.2f} / {f.max_deg:.1f}")
        for speed in ({}, fb._NOMINAL):
            f = fb.tilt_figures(rc, fb.run_ahrs(est(name, {**speed, **extra}), rc.samples))
            cells.append(f"{f.rms_deg:.2f} / {f.max_deg:.1f}")
        t1 = fb.time_to_one_degree_s(upside, fb.run_ahrs(est(name, extra), upside.samples))
        print(f"| {name} | {json.dumps(extra)} | " + " | ".join(cells) + f" | {t1:.2f} |",
              flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
