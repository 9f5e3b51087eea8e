"""Soak benchmark: every bundled board under every fault kind its devices can have, for as
long as asked, checked against the simulation's truth (plain script; not collected by pytest).

Run:  nice -n 10 .venv/bin/python tests/benchmarks/soak.py [--board seed-rc-vario]
      [--duration 3600] [--startups 40] [--seed 1] [--json FILE] [--quiet]
      .venv/bin/python tests/benchmarks/soak.py --combine A.json B.json ...

Each bundled board (``--board``, default: every one, one after the other), every chip
emulated at register level with its datasheet error model, flies its profile's scenario for
``--duration`` simulated seconds (``thermal`` with glides and thermals repeated, so the
altitude stays near launch however long the run; ``rc-flight`` cruises after its
aerobatics) with 1 % random bus errors on every device for the whole run (each transfer
fails with probability 0.01; on a UART each byte) plus one instance of every fault kind of
imuhal.emulation.faults on every device that can have it (tests/benchmarks/fault_truth.py
``Device.can_have``: the chip kinds its emulator models, such as the MPU-9250's and the
BMP280's stuck data-ready, a receiver reset on the GNSS, ``corrupt_byte`` on a UART,
``wrong_pressure`` on a barometer, a ``wild_value`` on each quantity the chip measures),
spread over the first 85 % of the run; near the end every factory calibration that can be
corrupted is, followed by a reset that makes the driver read it again (the plan is
printed). Every event is judged by the checker the fault matrix uses
(tests/benchmarks/fault_truth.py: wrong valid samples against the truth within the error
model's tolerance, NaN, out of order, by-design ``wrong_pressure`` reported apart with the
vario gate's verdict, unflagged wrong estimates). Per board it also reports:

* **crashes**: exceptions that escaped ``Pipeline.events`` (the run stops at the first);
* **delivered**: valid samples of each quantity against what its stream's rate promises
  over the run (what bus errors, recoveries and the faults cost);
* **start-up**: successful opens of the board with 1 % bus errors on all its devices, over
  ``--startups`` seeds;
* **memory**: resident set size after the board's first simulated minute and at its end
  (one board per process gives clean figures: ``--board``).

``--json FILE`` writes the reports (rewritten after every simulated minute, so a run cut
short leaves its figures so far); ``--combine`` prints one measure x board table from such
files. Figures for docs/reliability.md come from runs of this script.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
import time
import traceback
from collections import Counter
from collections.abc import Sequence
from dataclasses import fields
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

from tests.benchmarks import fault_truth
from tests.benchmarks.fault_truth import Device, Report

from imuhal.core.atomic import atomic_write_text
from imuhal.emulation import error_models_for, open_emulated
from imuhal.emulation.faults import BusErrors, FaultSpec
from imuhal.plugins.manager import Registry, load_registry
from imuhal.profile.bundled import bundled_profiles
from imuhal.profile.loader import load_profile
from imuhal.profile.model import BoardProfile

ERROR_RATE = 0.01
"""Random bus errors on every device, the whole run."""
SPANS_S = {"os_error": 0.2, "all_ones": 0.5, "all_zeros": 0.3, "absent": 2.0,
           "stuck_data_ready": 1.0, "frozen": 5.0, "late_polls": 0.5, "jitter": 10.0,
           "host_stall": 10.0}
"""How long each window kind lasts in the soak (``frozen`` long enough for the drivers'
repeated-word detection to have to act; ``jitter`` and ``host_stall`` long enough to take
many polls)."""
RATES = {"os_error": 0.5, "host_stall": 0.1}
"""``os_error``: half the transfers in its window fail; ``host_stall``: the host is
stalled a tenth of its window (20 ms stalls)."""
PLAN_END = 0.85
"""The faults are spread over the run up to this fraction of it; then the trims."""


def flight_schedule(duration_s: float) -> tuple[tuple[float, float], ...]:
    """A thermal-scenario climb schedule that stays near launch altitude for any duration:
    60 s gliding at -1.1 m/s then 30 s climbing at 2.2 m/s, over and over (the scenario's
    default ends in an endless glide, which after an hour would leave the MS5611's range)."""
    schedule: list[tuple[float, float]] = [(0.0, 0.0)]
    t = 5.0
    while t < duration_s:
        schedule += [(t, -1.1), (t + 60.0, 2.2)]
        t += 90.0
    return tuple(schedule)


def scenario_params(profile: BoardProfile, duration_s: float) -> dict[str, Any]:
    """What the board's scenario needs to last ``duration_s`` near launch altitude."""
    if profile.emulation.scenario == "thermal":
        return {"schedule": flight_schedule(duration_s)}
    return {}


def _slots(devices: Sequence[Device]) -> list[tuple[str, Device, int]]:
    """(kind, device, index) for every kind but the background ones on every device that
    can have it; a ``wild_value`` once for each quantity of the device."""
    out = []
    for kind in fault_truth.KINDS:
        if kind in ("bus_errors", "corrupt_trim"):
            continue
        for dev in devices:
            if not dev.can_have(kind):
                continue
            repeats = len(dev.wild_channels()) if kind == "wild_value" else 1
            out += [(kind, dev, i) for i in range(repeats)]
    return out


def fault_plan(devices: Sequence[Device], duration_s: float) -> list[FaultSpec]:
    """1 % random bus errors on every device, one instance of every other fault kind on
    every device that can have it, spread evenly up to PLAN_END of the run, then each
    corruptible factory calibration, a reset 0.5 s later making the driver read it again
    (a corrupted calibration is permanent, so it comes last)."""
    plan: list[FaultSpec] = [BusErrors(device=d.name, rate=ERROR_RATE) for d in devices]
    slots = _slots(devices)
    step = PLAN_END * duration_s / (len(slots) + 1)
    for n, (kind, dev, index) in enumerate(slots, start=1):
        start = round(n * step, 3)
        span = SPANS_S.get(kind)
        end = None if span is None else round(start + span, 3)
        fault = fault_truth.make_fault(kind, dev, start, end, rate=RATES.get(kind, ERROR_RATE),
                                       index=index)
        assert fault is not None, (kind, dev.name)  # _slots asked can_have
        plan.append(fault)
    trims = [d for d in devices if d.can_have("corrupt_trim")]
    late = (1.0 - PLAN_END) * duration_s / (len(trims) + 1)
    for n, dev in enumerate(trims, start=1):
        start = round(PLAN_END * duration_s + n * late, 3)
        plan.append(fault_truth.make_fault("corrupt_trim", dev, start))  # type: ignore[arg-type]
        if dev.can_have("reset"):
            plan.append(fault_truth.make_fault("reset", dev, start + 0.5))  # type: ignore[arg-type]
    return plan


def rss_mb() -> float:
    with open("/proc/self/statm") as f:
        pages = int(f.read().split()[1])
    return pages * os.sysconf("SC_PAGE_SIZE") / 1e6


def startup_trials(profile: BoardProfile, registry: Registry, attempts: int
                   ) -> tuple[int, int]:
    """(successful opens, attempts) of the board with 1 % bus errors on every device."""
    devices = [n for n, d in profile.devices.items() if d.enabled]
    ok = 0
    for seed in range(attempts):
        faults = [BusErrors(device=d, rate=ERROR_RATE) for d in devices]
        try:
            with open_emulated(profile, registry, seed=seed, faults=faults) as p:
                ok += all(d.present for d in p.devices.values())
        except Exception:
            pass
    return ok, attempts


class Checkpoint:
    """The reports so far, rewritten (atomically) to ``path`` after every chunk, so a run
    cut short leaves its figures up to its last simulated minute."""

    def __init__(self, path: str | None) -> None:
        self.path = path
        self.reports: list[Report] = []

    def write(self) -> None:
        if self.path:
            # not dataclasses.asdict: it rebuilds a Counter from its items, counting them
            data = [{f.name: getattr(r, f.name) for f in fields(r)} for r in self.reports]
            atomic_write_text(self.path, json.dumps(data, indent=1, default=str))


def soak(board: str, profile: BoardProfile, registry: Registry, report: Report,
         checkpoint: Checkpoint, progress: bool = True) -> None:
    """Fly ``board`` for ``report.duration_s`` under its fault plan, filling ``report``."""
    duration_s = report.duration_s
    plan = fault_plan(fault_truth.devices_of(profile, registry), duration_s)
    if progress:
        print(f"{board}: fault plan:", *(f"  {spec!r}" for spec in plan), sep="\n",
              file=sys.stderr)
    wall0 = time.perf_counter()
    report.rss_mb["start"] = rss_mb()
    try:
        pipeline = open_emulated(profile, registry, seed=report.seed, faults=plan,
                                 scenario_params=scenario_params(profile, duration_s))
    except Exception:
        report.crashes.append(traceback.format_exc())
        return
    rates = {f"{name} {spec.quantity.value}": spec.rate_hz
             for name, streams in pipeline.streams.items() for spec in streams}
    models = error_models_for(profile, registry, report.seed)
    checker = fault_truth.Checker(pipeline, plan, report, models)
    step = min(60.0, duration_s)
    try:
        while report.simulated_s < duration_s - 1e-9:
            chunk = min(step, duration_s - report.simulated_s)
            for event in pipeline.events(chunk):
                checker.handle(event)
            report.simulated_s += chunk
            report.rss_mb["end"] = rss_mb()
            if report.simulated_s == step:
                report.rss_mb["after 1 min"] = report.rss_mb["end"]
            report.wall_s = time.perf_counter() - wall0
            _finish(report, pipeline, rates)
            checkpoint.write()
            if progress:
                print(f"  {board}: {report.simulated_s:7.0f} s simulated, {report.wall_s:6.0f} s "
                      f"wall, RSS {report.rss_mb['end']:6.1f} MB, wrong valid "
                      f"{sum(report.wrong_valid.values())}, wrong estimates "
                      f"{sum(report.wrong_estimates.values())}", file=sys.stderr, flush=True)
    except Exception:
        report.crashes.append(traceback.format_exc())
    report.wall_s = time.perf_counter() - wall0
    _finish(report, pipeline, rates)
    pipeline.close()


def _finish(report: Report, pipeline: Any, rates: dict[str, float]) -> None:
    """The figures taken from the pipeline and the board so far."""
    done = report.simulated_s
    report.delivered = {key: (report.checked[key], rate * done)
                        for key, rate in rates.items() if key in report.checked}
    report.summary = pipeline.summary(simulated_s=done, wall_s=report.wall_s).describe()
    report.fault_log = list(pipeline.board.faults.log.events)
    report.injected = pipeline.board.faults.log.injected


def _gated(report: Report) -> str:
    """How many by-design wrong pressures the vario's gate rejected, of how many."""
    entries = report.by_design
    withheld = sum(e["gated"] is None for e in entries)
    return (f"{sum(e['gated'] is True for e in entries)} of {len(entries)}"
            + (f" ({withheld} while the vario was withheld)" if withheld else ""))


def _measures(report: Report) -> dict[str, str]:
    """One board's headline figures, by measure (the rows of the combined table)."""
    rss = report.rss_mb
    growth = rss.get("end", 0.0) - rss.get("after 1 min", rss.get("end", 0.0))
    ok, attempts = report.startups
    climbs = [e.get("climb_error_after", math.nan) for e in report.by_design]
    return {
        "simulated of asked / wall": f"{report.simulated_s:.0f} of {report.duration_s:.0f} s"
                                     f" / {report.wall_s:.0f} s",
        "crashes": str(len(report.crashes)),
        "NaN in valid samples or estimates": str(sum(report.nan.values())),
        "valid samples wrong against the truth": f"{sum(report.wrong_valid.values())} of "
                                                 f"{sum(report.checked.values()):,}",
        "valid samples out of time order": f"{sum(report.out_of_order.values())} "
                                           f"({report.flagged_out_of_order} flagged)",
        "unflagged wrong estimates": str(sum(report.wrong_estimates.values())),
        "estimates refused or withheld": str(sum(report.rejected_estimates.values())),
        "RSS growth after the first minute": f"{growth:.1f} MB ({rss.get('after 1 min', 0):.0f}"
                                             f" -> {rss.get('end', 0):.0f} MB)",
        "`wrong_pressure` rejected by the vario's gate": _gated(report),
        "worst climb error in the 2 s after it": f"{max(climbs):.2f} m/s" if climbs
                                                 else "none to judge",
        "`wrong_pressure` blended by the chip's filter (apart)": str(report.by_design_blended),
        "held by a hung chip within its stated detection time (apart)":
            str(report.frozen_held),
        "start-ups with 1 % bus errors": f"{ok}/{attempts}" if attempts else "not run",
    }


def combined(reports: Sequence[Report]) -> str:
    """One table: a row per measure, a column per board."""
    columns = [_measures(r) for r in reports]
    lines = ["| measure | " + " | ".join(r.board for r in reports) + " |",
             "|---|" + "---|" * len(reports)]
    lines += [f"| {m} | " + " | ".join(c[m] for c in columns) + " |" for m in columns[0]]
    return "\n".join(lines)


def markdown(report: Report) -> str:
    """One board's details: what was wrong and under which faults, what was flagged,
    delivered and how close the worst valid sample came to its tolerance."""
    lines = [f"{report.board}, {report.simulated_s:g} of {report.duration_s:g} s simulated, "
             f"seed {report.seed}, {report.wall_s:.0f} s wall.", "", combined([report])]
    for title, counts in (("Wrong valid samples", report.wrong_by_fault),
                          ("Unflagged wrong estimates", report.wrong_estimates_by_fault)):
        if counts:
            lines += ["", f"{title} by quantity and the faults in force:", "",
                      "| what | count | first |", "|---|---|---|"]
            lines += [f"| {k} | {v} | {report.first_wrong_s.get(k, math.nan):.2f} s |"
                      for k, v in sorted(counts.items())]
    lines += ["", "Flagged samples, by quantity and flag (first and last time):", "",
              "| samples | flag | count | first | last |", "|---|---|---|---|---|"]
    for key, (first, last, n) in sorted(report.flagged_spans.items()):
        what, flag = key.rsplit(" ", 1)
        lines.append(f"| {what} | {flag} | {n} | {first / 1e9:.1f} s | {last / 1e9:.1f} s |")
    lines += ["", "Valid samples delivered against the stream's rate, and the worst error / "
              "tolerance among them:", "",
              "| quantity | valid | promised | delivered | worst ratio |", "|---|---|---|---|---|"]
    lines += [f"| {k} | {n} | {promised:.0f} | {100 * n / promised:.1f} % | "
              f"{report.worst.get(k, math.nan):.2f} |"
              for k, (n, promised) in sorted(report.delivered.items()) if promised]
    return "\n".join(lines)


def load_reports(paths: Sequence[str]) -> list[Report]:
    """Reports from ``--json`` files, in order."""
    counters = {"nan", "checked", "wrong_valid", "wrong_by_fault", "out_of_order",
                "wrong_estimates", "wrong_estimates_by_fault", "rejected_estimates",
                "attitudes", "tilt_over"}
    out = []
    for path in paths:
        for data in json.loads(Path(path).read_text(encoding="utf-8")):
            report = Report(**data)
            for name in counters:
                setattr(report, name, Counter(getattr(report, name)))
            out.append(report)
    return out


def failed(report: Report) -> bool:
    """Whether the board's soak broke a promise."""
    # gated None: no vario estimate answered that pressure (the vario was withheld), so no
    # output carried it; a climb it pulled off later is a wrong estimate, counted above.
    return bool(report.crashes or report.nan or report.out_of_order or report.wrong_valid
                or report.wrong_estimates
                or any(entry["gated"] is False for entry in report.by_design))


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    boards = {Path(name).stem: path for name, path in bundled_profiles().items()}
    parser.add_argument("--board", default="all", choices=["all", *sorted(boards)],
                        help="the bundled board to soak (default: every one, in turn)")
    parser.add_argument("--duration", type=float, default=600.0, help="simulated seconds")
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--startups", type=int, default=40, help="start-up attempts per board")
    parser.add_argument("--json", metavar="FILE", help="also write the reports as JSON")
    parser.add_argument("--combine", nargs="+", metavar="JSON",
                        help="print the measure x board table of earlier --json files")
    parser.add_argument("--quiet", action="store_true", help="no progress lines")
    args = parser.parse_args(argv)
    if args.combine:
        print(combined(load_reports(args.combine)))
        return 0
    if not (math.isfinite(args.duration) and args.duration >= 60):
        parser.error("--duration must be at least 60 simulated seconds")
    registry = load_registry()
    checkpoint = Checkpoint(args.json)
    for board in sorted(boards) if args.board == "all" else [args.board]:
        profile = load_profile(boards[board], registry)
        report = Report(duration_s=args.duration, seed=args.seed, board=board)
        checkpoint.reports.append(report)
        report.startups = startup_trials(profile, registry, args.startups)
        soak(board, profile, registry, report, checkpoint, progress=not args.quiet)
        checkpoint.write()
        print(markdown(report))
        print("\nRun summary:\n\n```\n" + report.summary + "\n```")
        print("\nFault log:\n\n```\n" + "\n".join(report.fault_log) + "\n```\n", flush=True)
        for crash in report.crashes:
            print(f"\n{board} CRASH:\n" + crash, file=sys.stderr)
    return 1 if any(failed(r) for r in checkpoint.reports) else 0


if __name__ == "__main__":
    sys.exit(main())
