"""Where an emulated board's CPU goes, by layer (plain script; not collected by pytest).

Run:  .venv/bin/python -m tests.benchmarks.emulation_split [--duration 30] [--repeat 2]
          [--fifo-frames 8] [--other TREE] [--calls]

The seed paraglider vario (profiles/seed-paraglider-vario.yaml, ``thermal``, its
estimators) emulated with one frame per block, and with its MAX21100 read from the FIFO in
blocks of ``--fifo-frames``, is sampled on CPU time (``ITIMER_VIRTUAL``, every 0.5 ms of
user CPU: the pipeline's watchdog ticks on ``ITIMER_PROF`` and ``ITIMER_REAL``, so the two
do not meet). Each sample is put in one layer by the stack it interrupted:

- **simulation**: the scenario's truth (trajectories, attitude, air, magnetic field) and the
  chips' error models (imuhal.sim, but the chip and bus faces below);
- **chip emulators**: the register-level emulators (``*/emulator*.py`` of the chip
  plugins), their common base and measured instants (imuhal.sim.chip, .measured, .inputs);
- **bus glue**: the emulated bus and the board that hands the chips their inputs
  (imuhal.sim.emulated_bus, imuhal.emulation.board, .lines, .mounting);
- **fault layer**: the fault lines and schedule (imuhal.emulation.faults);
- **hardware path**: the rest (drivers, decoding, pipeline, estimators, sinks): what a
  board on real buses runs as well.

A sample inside the emulation is put in the layer of the innermost emulation frame (numpy
and the standard library count for their caller), so a chip emulator's call into the
simulation counts as simulation. Sampling, not tracing: cProfile's cost per call would
inflate the many small functions of these layers. The figures are shares of the run and
us of CPU per IMU sample (250 Hz), the best (least CPU) of ``--repeat`` runs.

``--calls`` counts the Python function calls each layer's code makes per IMU sample instead
(``sys.setprofile``): deterministic, so it compares two trees exactly where CPU figures on
a loaded machine cannot resolve a few per cent (a call is not a fixed cost, so it is the
shape of the work, not its time).

``--other TREE`` measures another tree (its ``src`` and ``plugins``, e.g. an exported
main) in a child process in the same minutes, alternating with this one, and prints the
ratios of this tree's figures to its.
"""

from __future__ import annotations

import argparse
import json
import os
import signal
import subprocess
import sys
import time
from collections import Counter
from pathlib import Path
from types import FrameType

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

LAYERS = ("simulation", "chip emulators", "bus glue", "fault layer", "hardware path")
RATE_HZ = 250.0
SAMPLE_S = 0.0005

_PROJECT = "/imuhal"  # imuhal, imuhal_chips, imuhal_filters (and their tests' packages)
_CHIP_FACES = ("/imuhal/sim/chip.py", "/imuhal/sim/measured.py", "/imuhal/sim/inputs.py")
_GLUE = ("/imuhal/sim/emulated_bus.py", "/imuhal/emulation/board.py",
         "/imuhal/emulation/lines.py", "/imuhal/emulation/mounting.py")


def layer_of(path: str) -> str | None:
    """The emulation layer a source file belongs to; None: not the emulation's."""
    path = path.replace(os.sep, "/")
    if path.endswith(_CHIP_FACES) or ("/imuhal_chips/" in path and "/emulator" in path):
        return "chip emulators"
    if path.endswith(_GLUE):
        return "bus glue"
    if path.endswith("/imuhal/emulation/faults.py"):
        return "fault layer"
    if "/imuhal/sim/" in path:
        return "simulation"
    return None


def sample_layer(frame: FrameType | None) -> str:
    """The layer of the innermost emulation frame of the stack, else the hardware path."""
    while frame is not None:
        layer = layer_of(frame.f_code.co_filename)
        if layer is not None:
            return layer
        frame = frame.f_back
    return "hardware path"


def measure(duration_s: float, fifo_frames: int | None) -> tuple[float, Counter[str]]:
    """(CPU s of the run, samples by layer) of one emulated run."""
    from tests.benchmarks.bench_blocks import SEED, board_yaml

    from imuhal.emulation import open_emulated
    from imuhal.plugins.manager import load_registry
    from imuhal.profile.loader import parse_profile

    registry = load_registry()
    profile = parse_profile(board_yaml(fifo_frames, SEED), str(SEED), registry)
    samples: Counter[str] = Counter()

    def handler(signum: int, frame: FrameType | None) -> None:
        samples[sample_layer(frame)] += 1

    with open_emulated(profile, registry, scenario="thermal") as pipeline:
        previous = signal.signal(signal.SIGVTALRM, handler)
        t0 = time.process_time()
        signal.setitimer(signal.ITIMER_VIRTUAL, SAMPLE_S, SAMPLE_S)
        try:
            for _ in pipeline.events(duration_s):
                pass
        finally:
            signal.setitimer(signal.ITIMER_VIRTUAL, 0.0)
            cpu = time.process_time() - t0
            signal.signal(signal.SIGVTALRM, previous)
    return cpu, samples


def calls(duration_s: float, fifo_frames: int | None) -> dict[str, float]:
    """{layer: Python function calls per IMU sample made in that layer's code, 'total'}:
    deterministic (traced with ``sys.setprofile``), so two trees compare exactly where CPU
    figures on a loaded machine cannot resolve a few per cent."""
    from tests.benchmarks.bench_blocks import SEED, board_yaml

    from imuhal.emulation import open_emulated
    from imuhal.plugins.manager import load_registry
    from imuhal.profile.loader import parse_profile

    registry = load_registry()
    profile = parse_profile(board_yaml(fifo_frames, SEED), str(SEED), registry)
    counted: Counter[str] = Counter()
    layers: dict[str, str] = {}

    def tracer(frame: FrameType, event: str, arg: object) -> None:
        if event != "call":
            return
        # a call into numpy or the standard library counts for the project code calling it
        f: FrameType | None = frame
        while f is not None:
            path = f.f_code.co_filename
            layer = layers.get(path)
            if layer is None:
                layer = layers[path] = layer_of(path) or (
                    "hardware path" if _PROJECT in path.replace(os.sep, "/") else "")
            if layer:
                counted[layer] += 1
                return
            f = f.f_back

    with open_emulated(profile, registry, scenario="thermal") as pipeline:
        events = pipeline.events(duration_s)
        sys.setprofile(tracer)
        try:
            for _ in events:
                pass
        finally:
            sys.setprofile(None)
    n = duration_s * RATE_HZ
    out = {layer: counted[layer] / n for layer in LAYERS}
    out["total"] = sum(counted.values()) / n
    return out


def figures(duration_s: float, fifo_frames: int | None, repeat: int) -> dict[str, float]:
    """{layer: us of CPU per IMU sample, 'total': the run's} of the least-CPU run."""
    cpu, samples = min((measure(duration_s, fifo_frames) for _ in range(max(1, repeat))),
                       key=lambda run: run[0])
    per_sample_us = cpu / (duration_s * RATE_HZ) * 1e6
    n = sum(samples.values()) or 1
    out = {layer: per_sample_us * samples[layer] / n for layer in LAYERS}
    out["total"] = per_sample_us
    return out


def _child(tree: Path, args: argparse.Namespace, fifo_frames: int | None) -> dict[str, float]:
    """:func:`figures` measured on ``tree``'s sources in a child process."""
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join(str(tree / p) for p in ("src", "plugins", "."))
    # this file, run on the other tree's sources (an older tree may not have it)
    cmd = [sys.executable, str(Path(__file__).resolve()), "--json",
           "--duration", str(args.duration), "--repeat", str(args.repeat)]
    if args.calls:
        cmd.append("--calls")
    if fifo_frames is not None:
        cmd += ["--only-fifo", str(fifo_frames)]
    else:
        cmd += ["--only-one-frame"]
    done = subprocess.run(cmd, cwd=tree, env=env, check=True, capture_output=True, text=True)
    return json.loads(done.stdout.strip().splitlines()[-1])


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--duration", type=float, default=30.0, help="simulated s per run")
    p.add_argument("--repeat", type=int, default=2, help="runs per mode; the least CPU kept")
    p.add_argument("--fifo-frames", type=int, default=8, help="the FIFO mode's block size")
    p.add_argument("--other", type=Path, default=None,
                   help="another tree to measure alternately (ratios: this one / it)")
    p.add_argument("--calls", action="store_true",
                   help="count Python calls per IMU sample by layer instead of sampling CPU")
    p.add_argument("--json", action="store_true", help=argparse.SUPPRESS)
    p.add_argument("--only-fifo", type=int, default=None, help=argparse.SUPPRESS)
    p.add_argument("--only-one-frame", action="store_true", help=argparse.SUPPRESS)
    args = p.parse_args(argv)
    def measured(fifo: int | None) -> dict[str, float]:
        return calls(args.duration, fifo) if args.calls else \
            figures(args.duration, fifo, args.repeat)

    if args.json:  # a child of --other: one mode, its figures as one JSON line
        print(json.dumps(measured(None if args.only_one_frame else args.only_fifo)))
        return 0
    modes = {"one frame per block": None, f"FIFO blocks of {args.fifo_frames}": args.fifo_frames}
    for mode, fifo in modes.items():
        mine = measured(fifo)
        other = None if args.other is None else _child(args.other.resolve(), args, fifo)
        what = "Python calls per IMU sample" if args.calls else \
            f"us of CPU per IMU sample, best of {args.repeat}"
        print(f"seed board, {mode}, {args.duration:g} s ({what}; load "
              f"{os.getloadavg()[0]:.1f}):")
        head = f"  {'layer':<16} {'this tree':>10} {'share':>7}"
        if other is not None:
            head += f" {'other':>10} {'share':>7} {'this/other':>10}"
        print(head)
        for layer in (*LAYERS, "total"):
            line = f"  {layer:<16} {mine[layer]:10.1f} {mine[layer] / mine['total']:7.1%}"
            if other is not None:
                ratio = mine[layer] / other[layer] if other[layer] else float("nan")
                line += (f" {other[layer]:10.1f} {other[layer] / other['total']:7.1%}"
                         f" {ratio:10.2f}")
            print(line)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
