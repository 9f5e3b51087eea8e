"""Where the hardware path's microseconds go per IMU sample (plain script; not collected by
pytest; needs py-spy, in the ``bench`` extra).

Run:  .venv/bin/python -m tests.benchmarks.hw_path_budget --recordings DIR [--duration 20]
      [--repeat 6] [--rate 500] [--case seed] [--bare]

Each case of tests/benchmarks/bench_hardware_path.py's ``--recordings`` (the seed board with
one frame per block, its MAX21100's FIFO in blocks of 8, the GY-91's MPU-9250 in blocks of
10; recorded into DIR the first time) is replayed ``--repeat`` times in a child process that
py-spy samples at ``--rate`` Hz (a sampling profile: cProfile's cost per call would inflate
the many small functions of the poll loop). Each stack sample inside ``Pipeline.blocks`` is
put in one share of the path by what it is running (first matching rule):

- *estimators, filter code*: inside ``Pipeline._fuse`` and in an estimator plugin's module;
- *estimators, routing and guard*: the rest of ``Pipeline._fuse`` (router, containment guard,
  estimate checks, the in-flight teachers);
- *replayed bus*: inside a driver call and in the bus layers or the replay (what stands in
  for the kernel's transfer on a board);
- *drivers*: inside a driver call, in a chip plugin or imuhal.drivers (decoding, flags, chip
  clock, schedule);
- *driver call*: the rest of a driver call (watchdog, ``_service``);
- *frame ledger*: imuhal.pipeline.accounting and the pipeline's calls into it;
- *validity*, *calibration and rotation* (with the in-flight learners);
- *poll loop*: everything else (heap, clock, hand-out, the sample objects built there).

The shares are multiplied by the case's CPU us per IMU sample from the fastest replay of the
same child (measured with the profiler attached: py-spy reads the process from outside, at
a small cost), so the rows add up to it. A second table splits the driver calls (drivers,
their replayed bus and the call's timing) by driver, with the calls per IMU sample counted
in one more replay in this process (not profiled).
"""

from __future__ import annotations

import argparse
import collections
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path
from typing import Any

from tests.benchmarks.bench_hardware_path import RECORDED_CASES

FIGURE = "us per IMU sample: "
"""How the child prints its figure (py-spy writes to the same stdout)."""

SHARES = (
    "estimators, filter code",
    "estimators, routing and guard",
    "replayed bus",
    "drivers",
    "driver call (watchdog, service)",
    "frame ledger",
    "validity",
    "calibration and rotation",
    "poll loop",
)


def share_of(frames: list[str]) -> str:
    """The share of the path one stack sample (outermost frame first, each ``func (path:
    line)``, from ``Pipeline.blocks`` down) belongs to."""
    names = [f.split(" (", 1)[0] for f in frames]
    paths = [f.split(" (", 1)[1] if " (" in f else "" for f in frames]
    if "Pipeline._fuse" in names:
        at = names.index("Pipeline._fuse")
        return SHARES[0] if any("imuhal_filters/" in p for p in paths[at:]) else SHARES[1]
    if "Pipeline._contained_service" in names:
        at = names.index("Pipeline._contained_service")
        inner = paths[at:]
        if any("/bus/" in p or "offline/replay.py" in p for p in inner):
            return SHARES[2]
        if any("imuhal_chips/" in p or "imuhal/drivers/" in p for p in inner):
            return SHARES[3]
        return SHARES[4]
    if any("accounting.py" in p for p in paths) or any(
            n in ("Pipeline._account", "Pipeline._account_slides", "Pipeline._gap")
            for n in names):
        return SHARES[5]
    if any(n.startswith(("validity_", "_validity", "_all_valid")) for n in names):
        return SHARES[6]
    if any(n.startswith(("calibrate_", "_mat_vec", "_rotate", "_corrected", "_calibrated",
                         "Pipeline._to_body", "Pipeline._learn"))
           or "calibration/" in p for n, p in zip(names, paths, strict=True)):
        return SHARES[7]
    return SHARES[8]


def driver_of(frames: list[str]) -> str | None:
    """The driver class a stack sample inside a driver call runs (None: not in one)."""
    names = [f.split(" (", 1)[0] for f in frames]
    if "Pipeline._contained_service" not in names:
        return None
    at = names.index("Pipeline._contained_service")
    return next((n.split(".", 1)[0] for n in names[at:] if "Driver." in n),
                "(outside the driver: watchdog, _service)")


def budget(raw: Path) -> tuple[dict[str, float], dict[str, float]]:
    """The shares (fractions of the samples inside ``Pipeline.blocks``) of py-spy's raw
    (collapsed) output ``raw``, and the shares of the driver calls by driver class (their
    bus transfers and timing included)."""
    counts: collections.Counter[str] = collections.Counter()
    drivers: collections.Counter[str] = collections.Counter()
    for line in raw.read_text().splitlines():
        stack, _, n = line.rpartition(" ")
        frames = stack.split(";")
        starts = [i for i, f in enumerate(frames) if f.startswith("Pipeline.blocks ")]
        if starts:
            counts[share_of(frames[starts[0]:])] += int(n)
            driver = driver_of(frames[starts[0]:])
            if driver is not None:
                drivers[driver] += int(n)
    total = sum(counts.values()) or 1
    return ({s: counts[s] / total for s in SHARES},
            {d: c / total for d, c in drivers.most_common()})


def polls(path: Path) -> tuple[int, collections.Counter[str]]:
    """One replay of ``path`` (not profiled): its IMU samples and the driver calls of each
    device."""
    from tests.benchmarks.bench_hardware_path import replay

    from imuhal.pipeline.pipeline import Pipeline
    from imuhal.plugins.manager import load_registry

    calls: collections.Counter[str] = collections.Counter()
    service = Pipeline._contained_service

    def counted(self: Pipeline, dev: Any, t_ns: int) -> Any:
        # under each class of the driver's: py-spy names a method by the class defining it
        for cls in type(dev.driver).__mro__:
            calls[cls.__name__] += 1
        return service(self, dev, t_ns)

    Pipeline._contained_service = counted  # type: ignore[method-assign]
    try:
        imu = replay(load_registry(), path)[0]
    finally:
        Pipeline._contained_service = service  # type: ignore[method-assign]
    return imu, calls


def child(path: Path, repeat: int, estimators: bool) -> None:
    """The profiled process: replay ``path`` ``repeat`` times; prints the fastest CPU us
    per IMU sample."""
    from tests.benchmarks.bench_hardware_path import replay

    from imuhal.plugins.manager import load_registry

    registry = load_registry()
    runs = [replay(registry, path, estimators=estimators) for _ in range(max(1, repeat))]
    print(f"{FIGURE}{min(r[2] / r[0] * 1e6 for r in runs)}")


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--recordings", type=Path, required=True,
                   help="bench_hardware_path's recordings directory (made when absent)")
    p.add_argument("--duration", type=float, default=20.0, help="recorded simulated s")
    p.add_argument("--repeat", type=int, default=6, help="replays in the profiled child")
    p.add_argument("--rate", type=int, default=500, help="py-spy samples per second")
    p.add_argument("--case", action="append", choices=sorted(RECORDED_CASES),
                   help="the cases to profile (default: all)")
    p.add_argument("--bare", action="store_true", help="without the profile's estimators")
    p.add_argument("--child", type=Path, help=argparse.SUPPRESS)
    args = p.parse_args(argv)
    if args.child is not None:
        child(args.child, args.repeat, not args.bare)
        return 0
    spy = shutil.which("py-spy")
    if spy is None:
        print("py-spy not found: pip install -e '.[bench]'", file=sys.stderr)
        return 2
    from tests.benchmarks.bench_hardware_path import recorded_cases

    cases = args.case or list(RECORDED_CASES)
    missing = [c for c in cases
               if not (args.recordings / f"{c}-{args.duration:g}s.imurec").exists()]
    if missing:  # records every case (and times them once, unprofiled)
        recorded_cases(args.recordings, args.duration, 1)
    rows: dict[str, tuple[float, tuple[dict[str, float], dict[str, float]]]] = {}
    counted = {case: polls(args.recordings / f"{case}-{args.duration:g}s.imurec")
               for case in cases}
    with tempfile.TemporaryDirectory() as tmp:
        for case in cases:
            raw = Path(tmp) / f"{case}.txt"
            rec = args.recordings / f"{case}-{args.duration:g}s.imurec"
            cmd = [spy, "record", "-r", str(args.rate), "-f", "raw", "-o", str(raw), "--",
                   sys.executable, "-m", "tests.benchmarks.hw_path_budget", "--recordings",
                   str(args.recordings), "--child", str(rec), "--repeat", str(args.repeat)]
            if args.bare:
                cmd.append("--bare")
            out = subprocess.run(cmd, check=True, capture_output=True, text=True).stdout
            figure = next(line for line in out.splitlines() if line.startswith(FIGURE))
            rows[case] = (float(figure[len(FIGURE):]), budget(raw))
    print("| share of the path | " + " | ".join(cases) + " |")
    print("| --- |" + " ---: |" * len(cases))
    for share in SHARES:
        print(f"| {share} | " + " | ".join(f"{us * parts[share]:.1f}"
                                          for us, (parts, _) in rows.values()) + " |")
    print("| all, CPU us per IMU sample | " + " | ".join(f"{us:.1f}" for us, _ in rows.values())
          + " |")
    print()
    print("| case | driver | calls per IMU sample | us per IMU sample | us per call |")
    print("| --- | --- | ---: | ---: | ---: |")
    for case, (us, (_, by_driver)) in rows.items():
        imu, calls = counted[case]
        for driver, part in by_driver.items():
            n = calls.get(driver, 0) / imu
            per_call = f"{us * part / n:.1f}" if n else ""
            print(f"| {case} | {driver} | {n:.2f} | {us * part:.1f} | {per_call} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
