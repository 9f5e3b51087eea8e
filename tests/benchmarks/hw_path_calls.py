"""The hardware path's CPU by pipeline call, per call and per IMU sample (plain script; not
collected by pytest).

Run:  .venv/bin/python -m tests.benchmarks.hw_path_calls --recordings DIR [--duration 20]
      [--repeat 3] [--case seed-fifo8] [--markdown]

Each case of tests/benchmarks/bench_hardware_path.py's ``--recordings`` (recorded into DIR
the first time) is replayed ``--repeat`` times through ``Pipeline.blocks`` with the
pipeline's calls wrapped, and the replay with the least CPU is kept. Each wrapped call's
thread CPU time is summed by what it did:

- ``service DEVICE data|empty``: ``Pipeline._contained_service`` (the driver call with its
  bus transfers, the watchdog and ``_service``), by device and by whether it handed out
  anything;
- ``fuse blocks`` / ``fuse samples:KINDS``: ``Pipeline._fuse`` (router, containment guard,
  estimators), by whether the step held blocks (a FIFO read) or which sample types;
- ``hand out DEVICE``: ``Pipeline._hand_out`` of a FIFO read (validity, frame ledger,
  calibration and rotation of its blocks), and ``process one DEVICE``: ``_process_one``, the
  same for a register poll's reading;
- ``rest``: the replay's CPU less all of the above (the poll loop, the heap, the clock, the
  ledger's per-poll bookkeeping, and the wrappers' own cost).

Thread CPU time (``time.thread_time_ns``) is read twice per wrapped call, a real system
call on this VM (about 1 us each), so the whole is dearer than an unwrapped replay (1.3 x,
159.4 against 120.6 us per IMU sample, session 22): compare the rows, and two trees with the
same script (run it with each tree's ``src`` and ``plugins`` first on ``PYTHONPATH``, side
by side on a loaded machine).
"""

from __future__ import annotations

import argparse
import collections
import os
import sys
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")

from tests.benchmarks.bench_blocks import GY91, SEED, board_yaml
from tests.benchmarks.bench_hardware_path import RECORDED_CASES, record, replay

from imuhal.pipeline.pipeline import Pipeline
from imuhal.plugins.manager import load_registry

Totals = dict[str, list[int]]
"""{part: [calls, thread CPU ns]}."""


class _Wrapped:
    """Pipeline's calls wrapped to sum their thread CPU time into ``totals`` (undone by
    ``restore``)."""

    def __init__(self) -> None:
        self.totals: Totals = collections.defaultdict(lambda: [0, 0])
        self._saved: dict[str, Any] = {}
        self._wrap("_contained_service", lambda p, a, r: (
            f"service {a[0].name} {'data' if r[0] else 'empty'}"))
        self._wrap("_process_one", lambda p, a, r: f"process one {a[0].name}")
        self._wrap_fuse()
        self._wrap_hand_out()

    def _add(self, key: str, ns: int) -> None:
        entry = self.totals[key]
        entry[0] += 1
        entry[1] += ns

    def _wrap(self, name: str, key: Callable[[Pipeline, tuple[Any, ...], Any], str]) -> None:
        original = self._saved[name] = getattr(Pipeline, name)
        clock, add = time.thread_time_ns, self._add

        def wrapped(pipeline: Pipeline, *args: Any) -> Any:
            t0 = clock()
            out = original(pipeline, *args)
            add(key(pipeline, args, out), clock() - t0)
            return out

        setattr(Pipeline, name, wrapped)

    def _wrap_fuse(self) -> None:
        original = self._saved["_fuse"] = Pipeline._fuse
        clock, add = time.thread_time_ns, self._add

        def fuse(pipeline: Pipeline, *args: Any) -> Any:
            queued = pipeline._fusion
            key = "fuse blocks" if pipeline._blocks_queued else "fuse samples:" + ",".join(
                sorted({type(s).__name__ for s in queued}))
            t0 = clock()
            out = original(pipeline, *args)
            add(key, clock() - t0)
            return out

        Pipeline._fuse = fuse  # type: ignore[method-assign,assignment]

    def _wrap_hand_out(self) -> None:
        original = self._saved["_hand_out"] = Pipeline._hand_out
        clock, add = time.thread_time_ns, self._add

        def hand_out(pipeline: Pipeline, dev: Any, frames: Any, reads: bool) -> Iterator[Any]:
            if type(frames) is not list:  # a register poll's readings: _process_one times them
                yield from original(pipeline, dev, frames, reads)
                return
            t0 = clock()
            out = list(original(pipeline, dev, frames, reads))  # the read's blocks processed
            add(f"hand out {dev.name}", clock() - t0)
            yield from out

        Pipeline._hand_out = hand_out  # type: ignore[method-assign,assignment]

    def restore(self) -> None:
        for name, original in self._saved.items():
            setattr(Pipeline, name, original)


def case_calls(path: Path, repeat: int) -> tuple[int, int, Totals]:
    """(IMU samples, CPU ns of the replay, the totals) of the fastest of ``repeat``
    replays of ``path`` with the calls wrapped."""
    registry = load_registry()
    best: tuple[int, int, Totals] | None = None
    for _ in range(max(1, repeat)):
        wrapped = _Wrapped()
        try:
            t0 = time.thread_time_ns()
            imu, _events, _cpu = replay(registry, path)
            total = time.thread_time_ns() - t0
        finally:
            wrapped.restore()
        if best is None or total < best[1]:
            best = (imu, total, dict(wrapped.totals))
    assert best is not None
    return best


def rows(imu: int, total_ns: int, totals: Totals) -> list[tuple[str, int, float, float]]:
    """(part, calls, us per call, us per IMU sample), dearest first, then ``rest`` and
    ``all``."""
    out = [(part, calls, ns / calls / 1e3, ns / imu / 1e3)
           for part, (calls, ns) in sorted(totals.items(), key=lambda kv: -kv[1][1])]
    accounted = sum(ns for _, ns in totals.values())
    out.append(("rest (loop, heap, clock, ledger bookkeeping, wrappers)", 0, 0.0,
                (total_ns - accounted) / imu / 1e3))
    out.append(("all", 0, 0.0, total_ns / imu / 1e3))
    return out


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--recordings", type=Path, required=True,
                   help="the recordings' directory (bench_hardware_path --recordings)")
    p.add_argument("--duration", type=float, default=20.0, help="recorded simulated s")
    p.add_argument("--repeat", type=int, default=3, help="replays; the fastest counts")
    p.add_argument("--case", choices=sorted(RECORDED_CASES), action="append",
                   help="the case(s) to replay (default: every one)")
    p.add_argument("--markdown", action="store_true", help="print markdown tables")
    args = p.parse_args(argv)
    args.recordings.mkdir(parents=True, exist_ok=True)
    for case in args.case or list(RECORDED_CASES):
        path = args.recordings / f"{case}-{args.duration:g}s.imurec"
        if not path.exists():
            record(load_registry(), path, args.duration,
                   board_yaml(RECORDED_CASES[case], GY91 if case.startswith("gy91") else SEED))
        imu, total, totals = case_calls(path, args.repeat)
        print(f"\n{case}: {imu} IMU samples, thread CPU us" if not args.markdown else
              f"\n{case} ({imu} IMU samples), thread CPU us:\n\n"
              "| part | calls | us per call | us per IMU sample |\n| --- | ---: | ---: | ---: |")
        for part, calls, per_call, per_imu in rows(imu, total, totals):
            if args.markdown:
                print(f"| {part} | {calls or ''} | {f'{per_call:.1f}' if calls else ''} | "
                      f"{per_imu:.1f} |")
            else:
                print(f"  {part:56s} {calls or '':>6} {f'{per_call:8.1f}' if calls else '':>8}"
                      f" {per_imu:7.1f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
