"""Every device's frame ledger with its chip's oscillator off (plain script; not collected by
pytest).

Run:  .venv/bin/python -m tests.benchmarks.clock_ledgers [--error 0.02] [--duration 20]
      [--boards gy91,seed-rc-vario] [--stall-ms 20,92]

Issue 25 gives the emulated chips an oscillator error of up to +-2 % and asks that
delivered + counted lost = produced for every device. The fault matrix flies the chips on
their nominal clocks (``oscillator_error`` 0, the emulators' default); this script flies
every bundled board (its profile's scenario, seed 1, no faults) twice: once with the
board's chips, in name order, alternately ``+error`` and ``-error`` fast, once with the
signs swapped (a master and its auto-read slave then run apart, as the stall tables of
docs/acquisition.md set them). Each accounted device's ledger is compared with the
measurements its chip made over the ledger's segments (``fault_matrix.ledgers_of``, the
matrix's own check). A ledger that counts the nominal rate shows as "ledger - chip" off by
about the error times the chip's count; "delivered - chip" above 0 means more samples were
handed out as new measurements than the chip made in those segments (repeats), below 0
with "lost" 0 that measurements were lost without a count.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

from tests.benchmarks.fault_matrix import ledgers_of

from imuhal.emulation import open_emulated
from imuhal.emulation.faults import HostStall
from imuhal.plugins.manager import load_registry
from imuhal.profile.loader import load_profile

BOARDS = ("seed-paraglider-vario", "seed-rc-vario", "gy91", "seed-gps-vario")
PROFILES = Path(__file__).resolve().parents[2] / "profiles"
ERROR = 0.02
DURATION_S = 20.0


def fly(board: str, error: float, sign: int, duration_s: float,
        stall_ms: float = 0.0) -> list[str]:
    """Table rows of one flight: every accounted device's ledger against its chip."""
    registry = load_registry()
    profile = load_profile(PROFILES / f"{board}.yaml", registry)
    faults = [HostStall(device="imu", start_s=1.0, every_s=1.0, stall_s=stall_ms / 1e3)] \
        if stall_ms else []
    with open_emulated(profile, registry, seed=1, faults=faults) as pipeline:
        errors: dict[str, float] = {}
        for i, (name, chip) in enumerate(sorted(pipeline.board.emulators.items())):
            if hasattr(chip, "oscillator_error"):
                chip.oscillator_error = errors[name] = sign * error * (1 if i % 2 == 0 else -1)
        for _ in pipeline.events(duration_s):
            pass
        rows = []
        for name, c in ledgers_of(pipeline).items():
            lost = c["produced"] - c["delivered"]
            rows.append(f"| {board} | {name} | {errors.get(name, 0.0) * 100:+.0f} % "
                        f"| {stall_ms:g} ms "
                        f"| {c['produced']} | {c['delivered']} | {lost} | {c['chip']} "
                        f"| {c['produced'] - c['chip']:+d} | {c['delivered'] - c['chip']:+d} |")
        return rows


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--error", type=float, default=ERROR, help="oscillator error (0.02: 2 %%)")
    p.add_argument("--duration", type=float, default=DURATION_S, help="simulated s per run")
    p.add_argument("--boards", default=",".join(BOARDS), help="comma-separated profiles")
    p.add_argument("--stall-ms", default="0",
                   help="comma-separated host stalls, ms, once a second from 1 s (0: none)")
    args = p.parse_args(argv)
    stalls = [float(s) for s in args.stall_ms.split(",")]
    print(f"{args.duration:g} s of each profile's scenario, seed 1, no faults but the host "
          f"stalls, chips' oscillators +-{args.error * 100:g} %\n")
    print("| board | device | its chip's clock | host stall | produced (ledger) | delivered "
          "| lost (ledger) | the chip's count | ledger - chip | delivered - chip |")
    print("| --- | --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: |")
    for board in args.boards.split(","):
        for stall_ms in stalls:
            for sign in (1, -1):
                print("\n".join(fly(board, args.error, sign, args.duration, stall_ms)),
                      flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
