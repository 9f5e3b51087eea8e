"""Polling and data-ready triggers under host stalls: frames lost and time-stamp errors
against the chip's own measurement instants (docs/acquisition.md, "Triggers").

Usage::

    .venv/bin/python docs/scripts/trigger_table.py [--seconds S] [--seed N] [--write]

Prints the ``trigger-stalls`` block of docs/acquisition.md as a generated block
(docs/scripts/docblock.py); ``--write`` replaces it in the page.

Each MPU-9250 board (gy91, seed-gps-vario) flies ``thermal`` for ``--seconds`` simulated
seconds (uncalibrated, seed ``--seed``) in two modes: ``poll`` (the profile as bundled: the
timer trigger, the driver's poll grid) and ``data-ready`` (the same profile with
``interrupt:`` on the MPU-9250: its emulated INT pin drives the line, imuhal.emulation.lines),
with a ``host_stall`` fault (imuhal.emulation.faults) of each length in STALLS_MS once a
second from 1 s on, and once without; the runs without a stall and with the longest are
repeated with the chip's clock 2 % fast (``oscillator_error``). Each valid IMU sample's
stamp is compared with the instant of the frame it carries (the chip's latest measurement
at or before the stamp). Printed as a
Markdown table: frames produced (the frame ledger's count, and the chip's own over the
ledger's segments), delivered and lost (the frame ledger), the line's edges not
read (overwritten: a newer sample had replaced theirs when the host came back; or dropped
from the kernel's full queue of 16), and the stamp error RMS and max in microseconds.
"""

from __future__ import annotations

import argparse
import math
import signal
import sys
from bisect import bisect_right

from docblock import ROOT, generated_by, write_block

from imuhal.core.samples import GyroSample
from imuhal.emulation import open_emulated
from imuhal.emulation.board import EmulatedBoard
from imuhal.emulation.faults import HostStall
from imuhal.plugins.manager import Registry, load_registry
from imuhal.profile.bundled import bundled_profiles
from imuhal.profile.loader import load_profile
from imuhal.profile.model import BoardProfile, InterruptConfig

BOARDS = ("gy91", "seed-gps-vario")
STALLS_MS = (0.0, 20.0, 144.0, 300.0)
"""The stalls of the FIFO table (acquisition_table.py), for comparison."""
OSCILLATOR_ERRORS = (0.0, 0.02)


def _data_ready(profile: BoardProfile) -> BoardProfile:
    """``profile`` with the MPU-9250's INT wired to a line (BCM GPIO 17 on a Pi)."""
    devices = dict(profile.devices)
    devices["imu"] = devices["imu"].model_copy(update={
        "interrupt": InterruptConfig(chip="gpiochip0", line=17, edge="rising")})
    return profile.model_copy(update={"devices": devices})


def run(registry: Registry, board: str, mode: str, stall_ms: float, oscillator_error: float,
        seconds: float, seed: int) -> dict[str, float]:
    profile = load_profile(bundled_profiles()[f"{board}.yaml"], registry)
    if mode == "data-ready":
        profile = _data_ready(profile)
    faults = [HostStall(device="imu", start_s=1.0, every_s=1.0, stall_s=stall_ms / 1e3)] \
        if stall_ms else []
    with open_emulated(profile, registry, scenario="thermal", seed=seed, faults=faults,
                       calibrated=False) as p:
        emulator = EmulatedBoard.of(p).emulators["imu"]
        emulator.oscillator_error = oscillator_error  # type: ignore[attr-defined]  # MPU-9250 only
        stamps = [e.t_ns for e in p.events(seconds)
                  if isinstance(e, GyroSample) and e.device == "imu" and e.valid]
        summary = p.summary()
        instants = emulator.measured_ns
        ledger = p.devices["imu"].ledger
        assert ledger is not None
        # each stamp is at or after the instant of the frame it carries (the poll, or the
        # line's edge): the chip's count over the ledger's segments from the frames carried
        counted = sum(emulator.frames_between(a, b) for a, b, _ in ledger.all_segments())
    frames = summary.frames["imu"]
    errors_us = [(t - instants[bisect_right(instants, t) - 1]) / 1e3 for t in stamps]
    line = summary.triggers.get("imu", {})
    return {**frames, "chip_produced": counted,
            "unread": line.get("overwritten", 0) + line.get("lost_edges", 0),
            "rms_us": math.sqrt(sum(e * e for e in errors_us) / len(errors_us)),
            "max_us": max(errors_us)}


def _row(board: str, mode: str, stall_ms: float, osc: float, r: dict[str, float]) -> str:
    other = sum(v for k, v in r.items() if k.startswith("lost_") and k != "lost_host_stall")
    return (f"| {board} | {mode} | {stall_ms:g} ms | {osc * 100:+g} % | {r['produced']:.0f} | "
            f"{r['chip_produced']:.0f} | {r['delivered']:.0f} | {r['lost_host_stall']:.0f} | "
            f"{other:.0f} | "
            f"{r['unread']:.0f} | {r['rms_us']:.0f} us | {r['max_us']:.0f} us |")


COLUMNS = ("board", "trigger", "stall", "chip clock", "produced", "the chip's count",
           "delivered",
           "lost: host stall", "lost: other", "edges not read", "stamp error RMS",
           "stamp error max")


BLOCK = "trigger-stalls"
PAGE = ROOT / "docs" / "acquisition.md"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--seconds", type=float, default=60.0)
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--write", action="store_true",
                        help=f"replace the {BLOCK} block of docs/{PAGE.name}")
    args = parser.parse_args(argv)
    # figures of emulated time must not depend on the host's load (acquisition_table.py)
    signal.signal(signal.SIGALRM, signal.SIG_IGN)
    registry = load_registry()
    cases = [(s, 0.0) for s in STALLS_MS] + [(s, o) for o in OSCILLATOR_ERRORS if o
                                             for s in (0.0, STALLS_MS[-1])]
    command = ["--seconds", f"{args.seconds:g}",
               *(["--seed", str(args.seed)] if args.seed != 1 else [])]
    lines = [f"Generated by `{generated_by(__file__, command)}`: `thermal` {args.seconds:g} s, "
             f"seed {args.seed}, uncalibrated, one host stall a second from 1 s on.", "",
             "| " + " | ".join(COLUMNS) + " |", "|---" * len(COLUMNS) + "|"]
    for board, mode in ((b, m) for b in BOARDS for m in ("poll", "data-ready")):
        for stall_ms, osc in cases:
            lines.append(_row(board, mode, stall_ms, osc,
                              run(registry, board, mode, stall_ms, osc, args.seconds,
                                  args.seed)))
            print(f"{board} {mode} {stall_ms:g} ms {osc:+g}", file=sys.stderr, flush=True)
    text = "\n".join(lines)
    print(text)
    if args.write:
        write_block(PAGE, BLOCK, text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
