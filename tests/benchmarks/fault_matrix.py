"""Fault matrix (issue 26): every bundled board x every fault kind of the fault API, alone
and three at once, at 0.1, 1 and 10 %, every valid sample and every estimate checked against
the simulation's truth (plain script; not collected by pytest).

Run:  nice -n 10 .venv/bin/python tests/benchmarks/fault_matrix.py [--seconds 10]
      [--boards gy91,seed-gps-vario] [--rates 0.001,0.01,0.1] [--kinds wild_value,reset]
      [--seed 1] [--json out.json] [--markdown] [--in-process] [--imu-fifo 8]
      .venv/bin/python tests/benchmarks/fault_matrix.py --combine a.json b.json [--seconds 10]

Each run opens one bundled board emulated (its profile's scenario, seed 1 or ``--seed``),
injects the faults through imuhal.emulation.faults, flies ``--seconds`` simulated seconds
and judges every event with the checker the soak shares (tests/benchmarks/fault_truth.py) at MARGIN
times the tolerance the chips' error models allow, with each board's own latency (two
periods of the device's stream plus the latency its stream spec declares: a chip filter's
delay). What a kind "at r" means:

* rate kinds (``bus_errors``, ``os_error``): each transfer fails with probability r;
* window kinds (``all_ones``, ``all_zeros``, ``absent``, ``stuck_data_ready``, ``frozen``,
  ``late_polls`` 10 ms, ``jitter`` up to 5 ms): windows of at most 0.5 s covering a
  fraction r of the flight, evenly spread;
* ``host_stall``: 20 ms stalls at random, r / 20 ms a second (the host stalled a fraction r);
* one-off kinds (``reset``, ``corrupt_trim``, ``wild_value``, ``wrong_pressure``,
  ``corrupt_byte``): r times the device's samples, evenly spread (``wild_value``: 1000
  times the chip's full scale on one axis, each quantity of the device in turn;
  ``wrong_pressure``: +300 Pa, valid by design and reported apart by the checker).

Every kind hits every device of the board that can have it (chip kinds where the emulator
models them, ``corrupt_byte`` on serial lines, ``wrong_pressure`` on barometers). "Three at
once" runs consecutive kinds of the list in threes. Per run it counts: crashes (an
exception out of ``Pipeline.events``), wrong valid samples (valid and farther from the truth
than MARGIN x tolerance; a GNSS velocity more than VELOCITY_MARGIN_M_S off), and unflagged
wrong estimates (a non-finite attitude or vertical estimate that is not a RejectedEstimate;
a climb rate more than CLIMB_MARGIN_M_S off the truth after SETTLE_S), the estimates
refused or withheld (by estimator), and the tilt of the attitudes handed out after SETTLE_S
(how many, how many more than TILT_MARGIN_DEG off the truth, the worst): a figure beside
the withheld count, not a failure.

Each run flies in a child process forked from the script's process, which loads the
registry and the profiles and flies nothing itself, so no run can carry state into another
(the runs of one process once differed by a frame from the same run alone, never traced);
``--in-process`` flies them one after another in the script's own process.

It also checks every device's frame ledger (imuhal.pipeline.accounting) against the chip's
own count (issue 25): for each device that accounts for a stream and whose emulator records
its measurement instants, delivered + lost = produced, and within each segment (a stretch
between reconfigurations) the ledger's produced frames equal the measurements the emulator
made over the segment's span (``ChipEmulator.frames_between``; for a stream stamped on its
chip's clock, a FIFO read, from the measurement nearest each end's stamp, which lies a few us
either side of it). A run where either fails is
listed with the device, the ledger's count and the chip's ("accounting"). Slots a hung chip
did not measure (``not_measured``, as its driver's reads proved) and slots a host-paced chip
never converted (``not_converted``) are neither produced nor lost, so they are outside both
sides of the comparison and shown in columns of their own.
"""

from __future__ import annotations

import argparse
import ctypes
import json
import math
import multiprocessing
import os
import signal
import sys
import time
import traceback
from collections.abc import Iterable, Iterator, Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

from tests.benchmarks.fault_truth import (
    KINDS,
    TILT_MARGIN_DEG,
    Checker,
    Device,
    Report,
    devices_of,
    make_fault,
)

from imuhal.emulation import error_models_for, open_emulated
from imuhal.emulation.faults import FaultSpec
from imuhal.pipeline import Pipeline
from imuhal.plugins.manager import Registry, load_registry
from imuhal.profile.bundled import bundled_profiles
from imuhal.profile.loader import load_profile
from imuhal.profile.model import BoardProfile

RATES = (0.001, 0.01, 0.1)
SEED = 1
"""The flights' seed unless ``--seed`` says another."""
MARGIN = 1.5
"""Every tolerance of the error model, times this (the "generous margin")."""
WINDOW_MAX_S = 0.5


def _windows(rate: float, seconds: float) -> Iterator[tuple[float, float]]:
    """Windows of at most WINDOW_MAX_S covering ``rate`` of ``seconds`` (after 1 s)."""
    total = rate * (seconds - 1.0)
    n = max(1, math.ceil(total / WINDOW_MAX_S))
    length = total / n
    step = (seconds - 1.0) / n
    for i in range(n):
        start = 1.0 + i * step + (step - length) / 2
        yield round(start, 4), round(start + length, 4)


def _instants(rate: float, seconds: float, rate_hz: float) -> list[float]:
    n = max(1, round(rate * rate_hz * (seconds - 1.0)))
    step = (seconds - 1.0) / n
    return [round(1.0 + (i + 0.5) * step, 4) for i in range(n)]


def faults_for(kind: str, dev: Device, rate: float, seconds: float) -> list[FaultSpec]:
    """The faults of ``kind`` at ``rate`` on ``dev`` ([] where it does not apply)."""
    # from 1 s: a board that cannot start under the fault is a start-up figure (the soak's
    # 40 start-ups), not a flight's
    if kind in ("bus_errors", "os_error", "host_stall"):
        slots: list[tuple[float, float | None]] = [(1.0, None)]
    elif kind in ("all_ones", "all_zeros", "absent", "stuck_data_ready", "frozen",
                  "late_polls", "jitter"):
        slots = list(_windows(rate, seconds))
    else:
        slots = [(t, None) for t in _instants(rate, seconds, dev.rate_hz)]
    faults = [make_fault(kind, dev, a, b, rate=rate, index=i) for i, (a, b) in enumerate(slots)]
    return [f for f in faults if f is not None]


@dataclass
class RunResult:
    board: str
    kinds: tuple[str, ...]
    rate: float
    faults: int
    checked: int = 0
    wrong_valid: dict[str, int] = field(default_factory=dict)
    wrong_estimates: dict[str, int] = field(default_factory=dict)
    rejected_estimates: int = 0
    rejected_by_source: dict[str, int] = field(default_factory=dict)
    """RejectedEstimate events by estimator instance."""
    attitudes: int = 0
    """Finite attitude estimates handed out after the checker's SETTLE_S."""
    tilt_over: int = 0
    """Of those, the ones more than the checker's TILT_MARGIN_DEG off the true tilt."""
    worst_tilt_deg: float = 0.0
    by_design: int = 0
    frozen_held: int = 0
    """Valid samples of a hung chip within its driver's stated detection time (apart)."""
    out_of_order: int | None = None
    """Valid samples older than a valid sample their device already gave for the same
    quantity (None: a ``--json`` of a run before the matrix counted them)."""
    crash: str = ""
    wall_s: float = 0.0
    seed: int = SEED
    """The flight's seed (``--json`` files from before ``--seed`` flew seed 1)."""
    ledgers: dict[str, dict[str, int]] = field(default_factory=dict)
    """Per accounted device: the ledger's counts, ``chip`` (the emulator's count over the
    ledger's segments) and ``segments_off`` (segments whose count differs from it)."""

    @property
    def accounting_off(self) -> list[str]:
        """The devices whose ledger does not balance or differs from the chip's count."""
        return [d for d, c in self.ledgers.items()
                if c["segments_off"] or c["delivered"] + sum(
                    v for k, v in c.items() if k.startswith("lost_")) != c["produced"]]


def ledgers_of(pipeline: Pipeline) -> dict[str, dict[str, int]]:
    """Every accounted device's frame ledger beside its chip's own count of the frames it
    produced within each of the ledger's segments (devices whose emulator keeps no record
    of its measurement instants are left out)."""
    out: dict[str, dict[str, int]] = {}
    for name, dev in pipeline.devices.items():
        chip = pipeline.board.emulators.get(name)
        ledger = dev.ledger
        if ledger is None or chip is None or not len(chip.measured_ns):
            continue
        segments = ledger.all_segments()
        # a frame stamped on its chip's clock (a FIFO read) is stamped at its measurement's
        # instant as estimated, a few us either side: the measurement it carries is the
        # nearest, not the latest completed by its stamp (0.4 us early took the one before)
        carried = ledger.period_ns // 2 if dev.buffered else 0
        measured = [chip.frames_between(a + carried, b + carried) for a, b, _ in segments]
        out[name] = {**ledger.counts(), "chip": sum(measured),
                     "within_segments": sum(n for _, _, n in segments),
                     "segments_off": sum(n != m for (_, _, n), m in
                                         zip(segments, measured, strict=True))}
    return out


def run_one(board: str, profile: BoardProfile, registry: Registry, kinds: Sequence[str],
            rate: float, seconds: float, devices: list[Device], seed: int = SEED) -> RunResult:
    plan: list[FaultSpec] = [f for kind in kinds for dev in devices
                             for f in faults_for(kind, dev, rate, seconds)]
    result = RunResult(board, tuple(kinds), rate, len(plan), seed=seed)
    if not plan:
        return result  # no device of the board can have it (corrupt_byte without a UART)
    wall0 = time.perf_counter()
    report = Report(duration_s=seconds, seed=seed)
    try:
        with open_emulated(profile, registry, seed=seed, faults=plan) as pipeline:
            checker = Checker(pipeline, plan, report, error_models_for(profile, registry, seed),
                              margin=MARGIN)
            for event in pipeline.events(seconds):
                checker.handle(event)
        result.ledgers = ledgers_of(pipeline)
    except Exception:
        result.crash = traceback.format_exc(limit=-3)
    result.checked = sum(report.checked.values())
    result.wrong_valid = {**dict(report.wrong_valid), **{f"NaN {k}": v
                                                        for k, v in report.nan.items()}}
    result.by_design = len(report.by_design)
    result.frozen_held = report.frozen_held
    result.out_of_order = sum(report.out_of_order.values())
    result.wrong_estimates = dict(report.wrong_estimates)
    result.rejected_estimates = sum(report.rejected_estimates.values())
    result.rejected_by_source = dict(report.rejected_estimates)
    result.attitudes = sum(report.attitudes.values())
    result.tilt_over = sum(report.tilt_over.values())
    result.worst_tilt_deg = max(report.worst_tilt_deg.values(), default=0.0)
    result.wall_s = time.perf_counter() - wall0
    return result


_PR_SET_PDEATHSIG = 1
"""prctl(2)'s option: the signal a child gets when its parent dies."""

def _die_with(parent: int) -> None:
    """Have the kernel end this child when its parent dies (Linux's PR_SET_PDEATHSIG): a
    matrix killed by SIGTERM or SIGKILL must not leave a run flying on. Elsewhere the child
    outlives its parent as before."""
    try:
        libc = ctypes.CDLL(None, use_errno=True)
        libc.prctl(_PR_SET_PDEATHSIG, signal.SIGKILL)
    except (OSError, AttributeError):
        return
    if os.getppid() != parent:  # the parent died before the prctl
        os._exit(1)


def run_forked(board: str, profile: BoardProfile, registry: Registry, kinds: Sequence[str],
               rate: float, seconds: float, devices: list[Device],
               seed: int = SEED) -> RunResult:
    """``run_one`` in a child forked from this process (see the module docstring); its
    result comes back through a pipe (a child that dies without one is a crash)."""
    context = multiprocessing.get_context("fork")
    receive, send = context.Pipe(duplex=False)

    parent = os.getpid()

    def child() -> None:
        _die_with(parent)
        send.send(run_one(board, profile, registry, kinds, rate, seconds, devices, seed))

    process = context.Process(target=child)
    process.start()
    send.close()
    try:
        result: RunResult = receive.recv()
    except EOFError:
        planned = sum(len(faults_for(kind, dev, rate, seconds)) for kind in kinds
                      for dev in devices)
        result = RunResult(board, tuple(kinds), rate, planned, seed=seed,
                           crash="the run's process died without a result")
    process.join()
    return result


def plans(rates: Sequence[float]) -> Iterator[tuple[tuple[str, ...], float]]:
    triples = [KINDS[i:i + 3] for i in range(0, len(KINDS), 3)]
    for rate in rates:
        for kind in KINDS:
            yield (kind,), rate
        for triple in triples:
            yield triple, rate


def _total(counts: Iterable[int | None]) -> str:
    """The sum, or "not counted" when a run did not count it."""
    values = list(counts)
    return "not counted" if None in values else str(sum(v for v in values if v is not None))


def markdown(results: list[RunResult], seconds: float) -> str:
    seeds = ", ".join(map(str, sorted({r.seed for r in results}))) or str(SEED)
    lines = [f"{seconds:g} s flights, seed {seeds}, margin x{MARGIN:g}", "",
             "| board | runs | crashes | valid samples checked | wrong valid | out of order | "
             "unflagged wrong estimates | rejected estimates | attitudes handed out | of them "
             f"more than {TILT_MARGIN_DEG:g} deg off | worst tilt (deg) | by design "
             "(wrong_pressure) | held by a hung chip (stated) | wall s |",
             "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for board in sorted({r.board for r in results}):
        rs = [r for r in results if r.board == board]
        lines.append(
            f"| {board} | {len(rs)} | {sum(bool(r.crash) for r in rs)} | "
            f"{sum(r.checked for r in rs):,} | {sum(sum(r.wrong_valid.values()) for r in rs)} | "
            f"{_total(r.out_of_order for r in rs)} | "
            f"{sum(sum(r.wrong_estimates.values()) for r in rs)} | "
            f"{sum(r.rejected_estimates for r in rs)} | {sum(r.attitudes for r in rs):,} | "
            f"{sum(r.tilt_over for r in rs)} | {max(r.worst_tilt_deg for r in rs):.1f} | "
            f"{sum(r.by_design for r in rs)} | {sum(r.frozen_held for r in rs)} | "
            f"{sum(r.wall_s for r in rs):.0f} |")
    bad = [r for r in results if r.crash or r.wrong_valid or r.out_of_order
           or r.wrong_estimates]
    for r in bad:
        lines.append(f"\n- {r.board} {'+'.join(r.kinds)} at {r.rate:g}: "
                     f"{r.wrong_valid or ''} {r.wrong_estimates or ''} "
                     f"{r.crash.strip().splitlines()[-1] if r.crash else ''}")
    return "\n".join([*lines, "", *accounting_markdown(results)])


def accounting_markdown(results: list[RunResult]) -> list[str]:
    """Per board and device: the runs whose ledger balanced and matched the chip's own
    count in every segment, the frames summed over the runs, and each run that did not."""
    lines = ["| board | device | runs | delivered + lost = produced = the chip's count | "
             "produced | the chip's count | delivered | lost | slots not converted | "
             "slots not measured (chip hung) |",
             "|---|---|---|---|---|---|---|---|---|---|"]
    off: list[str] = []
    for board in sorted({r.board for r in results}):
        rs = [r for r in results if r.board == board]
        for device in sorted({d for r in rs for d in r.ledgers}):
            held = [r for r in rs if device in r.ledgers]
            counts = [r.ledgers[device] for r in held]
            ok = sum(device not in r.accounting_off for r in held)
            lines.append(
                f"| {board} | {device} | {len(held)} | {ok} of {len(held)} | "
                f"{sum(c['within_segments'] for c in counts)} | "
                f"{sum(c['chip'] for c in counts)} | {sum(c['delivered'] for c in counts)} | "
                f"{sum(v for c in counts for k, v in c.items() if k.startswith('lost_'))} | "
                f"{sum(c.get('not_converted', 0) for c in counts)} | "
                f"{sum(c.get('not_measured', 0) for c in counts)} |")
            off += [f"- {board} {device}: {'+'.join(r.kinds)} at {r.rate:g}: ledger "
                    f"{r.ledgers[device]['within_segments']} within segments, chip "
                    f"{r.ledgers[device]['chip']}" for r in held
                    if device in r.accounting_off]
    return lines + (["", *off] if off else [])


def with_imu_fifo(profile: BoardProfile, fifo_frames: int) -> BoardProfile:
    """``profile`` with its device ``imu`` read from its FIFO every ``fifo_frames``
    periods (``--imu-fifo``)."""
    device = profile.devices["imu"]
    settings = {**device.settings, "read": "fifo", "fifo_frames": fifo_frames}
    return profile.model_copy(update={"devices": {
        **profile.devices, "imu": device.model_copy(update={"settings": settings})}})


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--seconds", type=float, default=10.0)
    parser.add_argument("--boards", default="", help="comma-separated (default: every one)")
    parser.add_argument("--rates", default=",".join(map(str, RATES)))
    parser.add_argument("--kinds", default="",
                        help="comma-separated kinds: only the runs holding one of them")
    parser.add_argument("--seed", type=int, default=SEED,
                        help=f"the flights' seed (default {SEED})")
    parser.add_argument("--json", default="")
    parser.add_argument("--markdown", action="store_true")
    parser.add_argument("--in-process", action="store_true",
                        help="fly every run in this process, not each in a forked child")
    parser.add_argument("--imu-fifo", type=int, default=0, metavar="N",
                        help="fly a copy of each board with its device imu set to read: fifo, "
                             "fifo_frames N")
    parser.add_argument("--combine", nargs="+", metavar="JSON", default=[],
                        help="print the tables of earlier runs' --json files, run nothing")
    args = parser.parse_args(argv)
    if args.combine:
        combined = [RunResult(**{**data, "kinds": tuple(data["kinds"])})
                    for path in args.combine
                    for data in json.loads(Path(path).read_text(encoding="utf-8"))]
        print(markdown(combined, args.seconds))
        return 0
    registry = load_registry()
    boards = {Path(name).stem: path for name, path in bundled_profiles().items()}
    chosen = [b for b in args.boards.split(",") if b] or sorted(boards)
    rates = [float(r) for r in args.rates.split(",")]
    wanted = {k for k in args.kinds.split(",") if k}
    results: list[RunResult] = []
    for board in chosen:
        profile = load_profile(boards[board], registry)
        if args.imu_fifo:
            profile = with_imu_fifo(profile, args.imu_fifo)
        devices = devices_of(profile, registry)
        for kinds, rate in plans(rates):
            if wanted and not wanted.intersection(kinds):
                continue
            run = run_one if args.in_process else run_forked
            r = run(board, profile, registry, kinds, rate, args.seconds, devices, args.seed)
            if not r.faults:
                continue
            results.append(r)
            print(f"{board} {'+'.join(kinds)} {rate:g}: {r.faults} faults, {r.checked} checked, "
                  f"wrong {r.wrong_valid or 0}, out of order {r.out_of_order}, "
                  f"estimates {r.wrong_estimates or 0}, rejected "
                  f"{r.rejected_estimates} {r.rejected_by_source or ''}, "
                  f"tilt > {TILT_MARGIN_DEG:g} deg {r.tilt_over} of "
                  f"{r.attitudes} (worst {r.worst_tilt_deg:.1f}){' CRASH' if r.crash else ''}"
                  f"{' ACCOUNTING ' + ','.join(r.accounting_off) if r.accounting_off else ''}"
                  f" ({r.wall_s:.1f} s)",
                  file=sys.stderr, flush=True)
            if r.crash:
                print(r.crash, file=sys.stderr)
            if args.json:
                Path(args.json).write_text(json.dumps([asdict(x) for x in results], indent=1))
    if args.markdown:
        print(markdown(results, args.seconds))
    bad = sum(bool(r.crash or r.wrong_valid or r.out_of_order or r.wrong_estimates
                   or r.accounting_off)
              for r in results)
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
