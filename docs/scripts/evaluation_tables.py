"""The tables of docs/evaluation.md from ``imuhal evaluate --json`` outputs (several runs
merged, e.g. one per DOF), and optionally their per-trial figure (the same figure as
``imuhal evaluate --plot``, drawn by imuhal.offline.plotting); with ``--defaults``, the one
table of every attitude estimator with its defaults, on BROAD and in the flight scenarios
(docs/evaluation.md and docs/estimators.md).

    imuhal evaluate ~/.cache/imuhal/broad --dof 9 --dof 6 -e vqf ... --json run1.json
    python docs/scripts/evaluation_tables.py run1.json run2.json > tables.md
    python docs/scripts/evaluation_tables.py run1.json run2.json --plot errors.png > tables.md
    python docs/scripts/evaluation_tables.py --defaults run1.json run2.json > defaults.md
    python docs/scripts/evaluation_tables.py --defaults --only decoupled d6.json d9.json

``--defaults`` reads, for each installed AHRS, the rows its defaults gave (label = its name;
``NAME offline=true`` for the offline column) and flies the flight benchmark's scenarios
(flight_benchmark.py: the calibrated seed board, seed 1) with the same defaults.
"""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Sequence
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "src"))
sys.path.insert(0, str(Path(__file__).resolve().parent))

from imuhal.evaluate.report import aggregate, markdown_report, summary_table
from imuhal.evaluate.runner import TrialResult
from imuhal.offline.plotting import check_figure_path, plot_trial_errors

BROAD_TRIALS = 30
"""BROAD's trials that can be had (39 published; 01-39 without 13, 17, 19, 20, 22, 23, 37-39,
docs/evaluation.md)."""


def load(path: str) -> list[TrialResult]:
    rows = json.loads(Path(path).read_text())["trials"]
    return [TrialResult(**{**r, "groups": tuple(r["groups"].split())}) for r in rows]


def _broad_mean(results: Sequence[TrialResult], label: str, dof: int, key: str,
                digits: int = 2) -> str:
    rows = [r for r in results if r.label == label and r.dof == dof]
    if not rows:
        return "-"
    mean = sum(getattr(r, key) for r in rows) / len(rows)
    text = f"{mean:.{digits}f}"
    return text if len(rows) == BROAD_TRIALS else f"{text} ({len(rows)} trials)"


def defaults_table(results: Sequence[TrialResult], duration_s: float,
                   only: Sequence[str] = ()) -> str:
    """Every installed AHRS with its defaults (or only those named): BROAD means and the
    flight figures."""
    import flight_benchmark as fb

    from imuhal.plugins.manager import load_registry

    reg = load_registry()
    profile = fb.calibrated_seed_profile(reg)
    thermal = fb.fly(profile, reg, "thermal", duration_s)
    rc = fb.fly(profile, reg, "rc-flight", min(duration_s, 60.0))
    gnss = thermal.with_gnss()
    tg = fb.TARGETS
    lines = [
        "Every attitude estimator with its defaults (nothing set but what the data dictates: "
        "the sample period and, for the Freescale filters, the rate and the site's field). "
        f"BROAD: `imuhal evaluate`, mean RMSE over its {BROAD_TRIALS} available trials, "
        "degrees; 9-DOF total, 6-DOF inclination (the magnetometer withheld), the offline "
        "mode's 9-DOF total where the estimator has one. Flight: the flight benchmark's "
        "calibrated seed board (seed 1, errors from 5 s; `thermal` "
        f"{duration_s:g} s with the nominal 10 m/s airspeed (target <= "
        f"{tg['thermal_nominal_deg']:g}) or the GNSS velocity (<= "
        f"{tg['thermal_velocity_deg']:g}), tilt RMS; `rc-flight` {min(duration_s, 60.0):g} s "
        f"with no speed source, tilt max (< {tg['rc_max_deg']:g})).", "",
        "| estimator | BROAD 9-DOF total | BROAD 6-DOF inclination | BROAD offline 9-DOF total "
        "| `thermal` tilt RMS, nominal airspeed | `thermal` tilt RMS, GNSS velocity "
        "| `rc-flight` tilt max |",
        "| --- | ---: | ---: | ---: | ---: | ---: | ---: |"]
    for name in fb.installed_ahrs(reg):
        if only and name not in only:
            continue
        nominal = fb.tilt_figures(thermal, fb.run_ahrs(fb.make(reg, name, fb._NOMINAL),
                                                       thermal.samples))
        velocity = fb.tilt_figures(thermal, fb.run_ahrs(fb.make(reg, name, {}), gnss))
        rcf = fb.tilt_figures(rc, fb.run_ahrs(fb.make(reg, name, {}), rc.samples))
        lines.append(fb._row([
            name, _broad_mean(results, name, 9, "total_deg"),
            # three digits: the target is VQF's 0.723 deg
            _broad_mean(results, name, 6, "inclination_deg", 3),
            _broad_mean(results, f"{name} offline=true", 9, "total_deg"),
            fb._mark(nominal.rms_deg, tg["thermal_nominal_deg"]),
            fb._mark(velocity.rms_deg, tg["thermal_velocity_deg"]),
            fb._mark(rcf.max_deg, tg["rc_max_deg"])]))
        print(f"{name} flown", file=sys.stderr, flush=True)
    return "\n".join(lines)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("results", nargs="+", metavar="RESULTS.json")
    parser.add_argument("--plot", metavar="FIGURE.png",
                        help="also draw every trial's errors (needs matplotlib)")
    parser.add_argument("--defaults", action="store_true",
                        help="print the one table of every estimator with its defaults (BROAD "
                        "and the flight scenarios) instead")
    parser.add_argument("--duration", type=float, default=120.0, metavar="S",
                        help="`thermal` length for --defaults (s; `rc-flight` at most 60)")
    parser.add_argument("--only", action="append", default=[], metavar="NAME",
                        help="with --defaults: only this estimator's row (repeatable; to "
                        "re-make the rows of an estimator whose code changed)")
    args = parser.parse_args()
    if args.plot:
        check_figure_path(args.plot)
    results = [r for p in args.results for r in load(p)]
    if args.defaults:
        print(defaults_table(results, args.duration, args.only))
        return
    groups = aggregate(results)
    print("```\n" + summary_table(groups) + "\n```\n")
    print(markdown_report(groups))
    if args.plot:
        plot_trial_errors(results, title="BROAD: RMSE per trial").save(args.plot)
        print(f"wrote {args.plot}", file=sys.stderr)


if __name__ == "__main__":
    main()
