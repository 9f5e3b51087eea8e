"""How often a BMP280's filtered output repeats byte for byte (plain script; not collected by
pytest): what telling a new conversion from an old one by its data bytes would get wrong.

Run:  .venv/bin/python -m tests.benchmarks.bmp280_repeats [--duration 20]
      [--scenarios thermal,static] [--mode normal]

The BMP280 has no data-ready bit and no conversion counter, so one candidate for following a
chip clock a few percent off (docs/acquisition.md, "Ledgers with the chips' clocks off") is
to take a read whose six data bytes (pressure and temperature, 20 bits each) equal the read
before's as the same conversion. That fails where the chip made a new conversion with the
same bytes: a quiet chip with the IIR filter repeats its output. gy91's profile (its
BMP280's settings; ``--mode`` overrides its mode), every bundled scenario, seed 1, its chip
on its nominal clock, flown fault-free and at 10 % bus errors (the fault matrix's
``bus_errors``): for each pair of consecutive good reads of the driver, whether the bytes
are the same and whether the chip measured in between (its own record,
``ChipEmulator.measured_ns``). "new but same bytes" is what the byte test would take for a
repeat.
"""

from __future__ import annotations

import argparse
import itertools
import sys
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

from tests.benchmarks.fault_matrix import faults_for
from tests.benchmarks.fault_truth import devices_of

from imuhal.bus.spy import Transfer
from imuhal.emulation import open_emulated
from imuhal.plugins.manager import load_registry
from imuhal.profile.loader import load_profile
from imuhal_chips.bmp280 import registers as r

PROFILE = Path(__file__).resolve().parents[2] / "profiles" / "gy91.yaml"
SCENARIOS = ("thermal", "static", "elevator", "rc-flight", "tumble", "magnet")
DURATION_S = 20.0
BUS_ERROR_RATE = 0.1
_DATA = slice(4, 10)
"""The six data bytes (pressure, temperature) in the poll burst from the status register."""


def fly(scenario: str, duration_s: float, bus_errors: bool, mode: str | None) -> dict[str, int]:
    """Counts of consecutive good reads of gy91's barometer: new or not, bytes same or not."""
    registry = load_registry()
    profile = load_profile(PROFILE, registry)
    if mode is not None:
        profile.devices["baro"].settings["mode"] = mode
    faults = []
    if bus_errors:
        baro = next(d for d in devices_of(profile, registry) if d.name == "baro")
        faults = faults_for("bus_errors", baro, BUS_ERROR_RATE, duration_s)
    reads: list[tuple[bytes, int]] = []
    chips: list[Any] = []
    address = profile.devices["baro"].address

    def observe(t: Transfer) -> None:
        # the driver's poll burst as it read it (a failed transfer read nothing), and how
        # many measurements the chip had recorded by then
        if t.target == address and t.written == bytes((r.POLL_BURST_START,)) \
                and len(t.read) == r.POLL_BURST_LENGTH and not t.error and chips:
            reads.append((t.read[_DATA], len(chips[0].measured_ns)))

    with open_emulated(profile, registry, seed=1, scenario=scenario, faults=faults,
                       trace=observe) as pipeline:
        chips.append(pipeline.board.emulators["baro"])
        for _ in pipeline.events(duration_s):
            pass
    counts = {"pairs": 0, "new, same bytes": 0, "new, bytes differ": 0,
              "old, same bytes": 0, "old, bytes differ": 0}
    for (data_a, n_a), (data_b, n_b) in itertools.pairwise(reads):
        counts["pairs"] += 1
        new = "new" if n_b > n_a else "old"
        same = "same bytes" if data_a == data_b else "bytes differ"
        counts[f"{new}, {same}"] += 1
    return counts


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--duration", type=float, default=DURATION_S, help="simulated s per run")
    p.add_argument("--scenarios", default=",".join(SCENARIOS), help="comma-separated")
    p.add_argument("--mode", choices=("normal", "forced"), default=None,
                   help="the BMP280's mode (default: the profile's)")
    args = p.parse_args(argv)
    print(f"gy91's BMP280, {args.duration:g} s of each scenario, seed 1, nominal clock\n")
    print("| scenario | bus errors | read pairs | new conversion, same bytes | new, bytes "
          "differ | no new conversion (same bytes) | share of new conversions with the "
          "bytes before |")
    print("| --- | ---: | ---: | ---: | ---: | ---: | ---: |")
    for scenario in args.scenarios.split(","):
        for bus_errors in (False, True):
            c = fly(scenario, args.duration, bus_errors, args.mode)
            new = c["new, same bytes"] + c["new, bytes differ"]
            share = c["new, same bytes"] / new if new else 0.0
            print(f"| {scenario} | {BUS_ERROR_RATE * 100 if bus_errors else 0:g} % "
                  f"| {c['pairs']} | {c['new, same bytes']} | {c['new, bytes differ']} "
                  f"| {c['old, same bytes']} | {share * 100:.1f} % |", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
