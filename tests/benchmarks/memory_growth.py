"""Resident memory of a long emulated run, minute by minute (plain script; not collected by
pytest): does it grow with the run, or level off after its start?

Run:  nice -n 10 .venv/bin/python tests/benchmarks/memory_growth.py [--board seed-gps-vario]
      [--duration 900] [--every 60] [--bus-errors 0.01] [--seed 1]

The board flies its profile's scenario (``thermal`` kept near launch altitude as the soak
flies it) for ``--duration`` simulated seconds with ``--bus-errors`` random bus errors on
every device (the soak's background fault, no other fault: a fault kind first met mid-run
loads code and fills caches, which is start-up, not growth). Every ``--every`` simulated
seconds it prints the resident set size (``/proc/self/statm``, after a garbage collection)
and the emulators' records of their measurement instants (``ChipEmulator.measured_ns``:
instants held, and runs where the record keeps runs). The growth per 1,000 simulated s is
taken from the first minute to the end. docs/reliability.md keeps the figures.

``--trace N`` also traces the Python heap from the first checkpoint on (tracemalloc, one
frame, which slows the run severalfold): at every later checkpoint it prints the heap
allocated since the first checkpoint and still alive, and the ``N`` source lines that hold
most of it, so RSS growth can be split into Python objects (and where they were made) and
the rest (allocator pages, native libraries). The RSS of a traced run includes tracemalloc's
own bookkeeping: take RSS figures from an untraced run. ``--allocators`` prints, at each
checkpoint, what CPython's object allocator (its 1 MiB arenas, and the bytes of live
objects in them) and C malloc (in use, free in its heap, mmapped) hold, the two places RSS
comes from besides code.
"""

from __future__ import annotations

import argparse
import ctypes
import ctypes.util
import gc
import os
import re
import sys
import tempfile
import time
import tracemalloc
from collections.abc import Sequence
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

from tests.benchmarks.soak import rss_mb, scenario_params

from imuhal.emulation import open_emulated
from imuhal.emulation.faults import BusErrors
from imuhal.plugins.manager import load_registry
from imuhal.profile.bundled import bundled_profiles
from imuhal.profile.loader import load_profile


def _records(emulators: dict[str, object]) -> str:
    """Each emulator's record of its instants: held (and runs, where it keeps runs)."""
    parts = []
    for name, emulator in emulators.items():
        record = getattr(emulator, "measured_ns", None)
        if record is None or not len(record):
            continue
        runs = getattr(record, "runs", None)
        parts.append(f"{name} {len(record)}" + ("" if runs is None else f" in {runs} runs"))
    return ", ".join(parts)


class _MallInfo2(ctypes.Structure):
    _fields_ = [(name, ctypes.c_size_t) for name in (
        "arena", "ordblks", "smblks", "hblks", "hblkhd", "usmblks", "fsmblks", "uordblks",
        "fordblks", "keepcost")]


_MAPPED_BEFORE: dict[str, int] = {}
"""The resident kB per mapped file at the previous checkpoint (``_grown_mappings``)."""


def _grown_mappings(top: int = 3) -> str:
    """The mapped files (shared libraries, compiled extensions) whose resident pages grew
    since the previous checkpoint, most first: code faulted in the first time it runs."""
    now: dict[str, int] = {}
    name = ""
    with open("/proc/self/smaps") as f:
        for line in f:
            head = line.split()
            if "-" in head[0] and not head[0].endswith(":"):
                name = head[5] if len(head) > 5 else "[anon]"
            elif head[0] == "Rss:":
                now[name] = now.get(name, 0) + int(head[1])
    grown = sorted(((kb - _MAPPED_BEFORE.get(n, 0), n) for n, kb in now.items()
                    if n.startswith("/")), reverse=True)
    first = not _MAPPED_BEFORE
    _MAPPED_BEFORE.clear()
    _MAPPED_BEFORE.update(now)
    if first:
        return ""
    return "; files grown: " + (", ".join(f"{Path(n).name} +{kb} kB"
                                          for kb, n in grown[:top] if kb > 0) or "none")


def _allocators() -> str:
    """The RSS by kind (anonymous memory, file-backed pages: code and mapped files, shared
    memory) and what the two allocators under the anonymous part hold: CPython's object
    allocator (pymalloc:
    1 MiB arenas, and the bytes of live objects in them) and C malloc (glibc ``mallinfo2``:
    bytes in use from the heap and in mmapped blocks, numpy's arrays among them)."""
    saved = os.dup(2)
    with tempfile.TemporaryFile(mode="w+") as f:
        os.dup2(f.fileno(), 2)  # _debugmallocstats writes to the C stderr
        try:
            sys._debugmallocstats()
        finally:
            os.dup2(saved, 2)
            os.close(saved)
        f.seek(0)
        text = f.read()

    def stat(label: str) -> int:
        m = re.search(rf"# {label}\s*=\s*([\d,]+)", text)
        return int(m.group(1).replace(",", "")) if m else -1

    with open("/proc/self/status") as f:
        kinds = dict(line.split(":", 1) for line in f if line.startswith("Rss"))
    rss = ", ".join(f"{k[3:].lower()} {int(v.split()[0]) / 1e3:.2f}" for k, v in kinds.items())
    out = (f"RSS by kind (MB): {rss}; "
           f"pymalloc {stat('arenas allocated current')} arenas "
           f"(high-water {stat('arenas highwater mark')}), "
           f"{stat('bytes in allocated blocks') / 1e6:.2f} MB in objects")
    libc = ctypes.CDLL(ctypes.util.find_library("c") or "libc.so.6")
    if hasattr(libc, "mallinfo2"):
        libc.mallinfo2.restype = _MallInfo2
        info = libc.mallinfo2()
        out += (f"; malloc {info.uordblks / 1e6:.2f} MB in use, {info.fordblks / 1e6:.2f} MB "
                f"free in its heap, {info.hblkhd / 1e6:.2f} MB mmapped")
    return out + _grown_mappings()


def _traced_growth(base: tracemalloc.Snapshot, now: tracemalloc.Snapshot, top: int) -> None:
    """The Python heap allocated since ``base`` and still alive, and the ``top`` lines that
    hold most of it (tracemalloc's own records left out; its bookkeeping, which the RSS of
    a traced run includes, printed apart)."""
    skip = [tracemalloc.Filter(False, tracemalloc.__file__)]
    base, now = base.filter_traces(skip), now.filter_traces(skip)
    grown = sum(s.size_diff for s in now.compare_to(base, "filename"))
    print(f"    Python heap {grown / 1e6:+.3f} MB since the first checkpoint (tracemalloc's "
          f"own bookkeeping {tracemalloc.get_tracemalloc_memory() / 1e6:.2f} MB); held by:")
    for stat in now.compare_to(base, "lineno")[:top]:
        frame = stat.traceback[0]
        print(f"    {stat.size_diff / 1e3:+9.1f} kB {stat.count_diff:+7d} blocks  "
              f"{frame.filename}:{frame.lineno}")


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--board", default="seed-gps-vario")
    parser.add_argument("--duration", type=float, default=900.0, help="simulated seconds")
    parser.add_argument("--every", type=float, default=60.0, help="simulated seconds")
    parser.add_argument("--bus-errors", type=float, default=0.01)
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--allocators", action="store_true",
                        help="print what pymalloc and C malloc hold at each checkpoint")
    parser.add_argument("--trace", type=int, default=0, metavar="N",
                        help="trace the Python heap and print the N lines that grew most")
    args = parser.parse_args(argv)

    registry = load_registry()
    profile = load_profile(bundled_profiles()[f"{args.board}.yaml"], registry)
    faults = [BusErrors(device=name, rate=args.bus_errors)
              for name in profile.devices] if args.bus_errors else []
    wall0 = time.perf_counter()
    first: tuple[float, float] | None = None
    base: tracemalloc.Snapshot | None = None
    with open_emulated(profile, registry, seed=args.seed, faults=faults,
                       scenario_params=scenario_params(profile, args.duration)) as pipeline:
        done = 0.0
        while done < args.duration - 1e-9:
            chunk = min(args.every, args.duration - done)
            for _ in pipeline.events(chunk):
                pass
            done += chunk
            gc.collect()
            rss = rss_mb()
            if first is None:
                first = (done, rss)
                if args.trace:
                    # from the first checkpoint on only: what grows after the start-up
                    # (tracing from the start costs several times the run)
                    tracemalloc.start(1)
                    base = tracemalloc.take_snapshot()
            print(f"{done:7.0f} s simulated, {time.perf_counter() - wall0:6.0f} s wall, RSS "
                  f"{rss:6.2f} MB; records: {_records(pipeline.board.emulators)}",  # type: ignore[attr-defined]  # emulated board
                  flush=True)
            if args.allocators:
                print(f"    {_allocators()}", flush=True)
            if base is not None and done > first[0]:
                _traced_growth(base, tracemalloc.take_snapshot(), args.trace)
    assert first is not None
    if done > first[0]:
        per_ks = (rss - first[1]) / (done - first[0]) * 1000
        print(f"growth from {first[0]:.0f} s to {done:.0f} s: {rss - first[1]:+.2f} MB, "
              f"{per_ks:+.2f} MB per 1,000 simulated s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
