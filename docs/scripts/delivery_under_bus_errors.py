"""Delivery of every device of every bundled board under transient bus errors: against a
fault-free run, against the configured rate, and the frame ledger against the chip's count.

Usage::

    .venv/bin/python docs/scripts/delivery_under_bus_errors.py [--table fault-free|configured]
        [--seconds S] [--rate R] [--seeds N] [--write]

Each bundled board flies ``thermal`` for ``--seconds`` simulated seconds after a 1 s start-up,
uncalibrated, with ``bus_errors`` of probability ``--rate`` on every device (imuhal.emulation.
faults, as a profile's ``faults`` would), once per seed 1..``--seeds``, and once fault-free
with seed 1. One flight loop gives two tables:

* ``fault-free`` (the ``delivery-table`` block of docs/reliability.md, "Why the MPU-9250
  boards lost a quarter of their samples"): per device and quantity, the valid samples per
  second of the fault-free and the faulty seed-1 flights, the delivered fraction (faulty over
  fault-free), the device's bus errors and the driver's reconfigurations;
* ``configured`` (the ``delivery-configured`` block of docs/acquisition.md, "At 1 % bus
  errors"): the configured rate (the stream spec's ``rate_hz``, read back from the chip: what
  the profile asked for), the valid samples per second delivered (the lowest over the seeds)
  and their share of the configured rate, and, for the device's accounted stream
  (imuhal.pipeline.accounting), produced, delivered and lost by cause summed over the seeds,
  the slots a host-paced chip never converted, and whether in every flight delivered + lost
  = produced and, segment by segment, produced = the chip's own count (the emulator's record
  of its measurement instants, ``ChipEmulator.frames_between``).

Serial devices (the GNSS receiver) are listed but not held to 95 %: a UART has no retry, so
``bus_errors`` (each byte corrupted or dropped with probability ``rate``) leave 0.99^100 of a
100-byte frame, which the checksum then rejects (docs/reliability.md). ``--table`` prints one
table (default ``fault-free``); ``--write`` flies what both need and writes both blocks.
"""

from __future__ import annotations

import argparse
import sys
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path

from imuhal.bus.base import BusKind
from imuhal.core.samples import Quantity, Sample
from imuhal.emulation import open_emulated
from imuhal.emulation.faults import BusErrors
from imuhal.pipeline import Pipeline
from imuhal.pipeline.accounting import CAUSES, NOT_CONVERTED
from imuhal.plugins.manager import Registry, load_registry
from imuhal.profile.bundled import bundled_profiles
from imuhal.profile.loader import load_profile

sys.path.insert(0, str(Path(__file__).resolve().parent))
from docblock import generated_by, write_block

SETTLE_S = 1.0
THRESHOLD = 0.95
DOCS = Path(__file__).resolve().parents[1]
BLOCKS = {"fault-free": (DOCS / "reliability.md", "delivery-table"),
          "configured": (DOCS / "acquisition.md", "delivery-configured")}


@dataclass
class Flight:
    """One flight of one board: valid samples per (device, quantity) after the start-up,
    and per device its bus errors, reconfigurations, configured rates and frame ledger."""

    valid: Counter[tuple[str, Quantity]] = field(default_factory=Counter)
    bus_errors: dict[str, int] = field(default_factory=dict)
    reconfigurations: dict[str, int] = field(default_factory=dict)
    configured_hz: dict[tuple[str, Quantity], float] = field(default_factory=dict)
    serial: set[str] = field(default_factory=set)
    ledgers: dict[str, tuple[Quantity, dict[str, int], bool]] = field(default_factory=dict)
    """Per accounted device: its stream, its counts, and whether every segment's count
    equals the chip's (True when the emulator keeps no record to compare with)."""
    within: dict[str, tuple[int, int | None]] = field(default_factory=dict)
    """Per accounted device: produced within segments, and the chip's count over them."""


def fly(registry: Registry, board: str, seconds: float, rate: float, seed: int) -> Flight:
    profile = load_profile(bundled_profiles()[board], registry)
    devices = [n for n, d in profile.devices.items() if d.enabled]
    faults = [BusErrors(device=d, rate=rate) for d in devices] if rate else []
    flight = Flight()
    with open_emulated(profile, registry, seed=seed, faults=faults, calibrated=False) as p:
        start_ns = p.clock.now_ns() + round(SETTLE_S * 1e9)
        for e in p.events(seconds + SETTLE_S):
            if isinstance(e, Sample) and e.valid and e.t_ns >= start_ns:
                flight.valid[(e.device, e.channel)] += 1
        summary = p.summary()
        _take_ledgers(p, flight)
    flight.bus_errors = dict(summary.bus_errors)
    flight.reconfigurations = {n: c["reconfigurations"] for n, c in summary.driver.items()}
    return flight


def _take_ledgers(p: Pipeline, flight: Flight) -> None:
    for name, dev in p.devices.items():
        if dev.driver.link.kind is BusKind.SERIAL:
            flight.serial.add(name)
        for spec in p.streams.get(name, ()):
            if spec.rate_hz:
                flight.configured_hz[(name, spec.quantity)] = spec.rate_hz
        ledger = dev.ledger
        if ledger is None:
            continue
        segments = ledger.all_segments()
        chip = p.board.emulators[name]
        measured = [chip.frames_between(a, b) for a, b, _ in segments] \
            if len(chip.measured_ns) else None
        equal = measured is None or measured == [n for _, _, n in segments]
        flight.ledgers[name] = (ledger.channel, ledger.counts(), equal)
        flight.within[name] = (sum(n for _, _, n in segments),
                               None if measured is None else sum(measured))


def fault_free_table(boards: dict[str, tuple[Flight, list[Flight]]], seconds: float
                     ) -> list[str]:
    lines = ["| board | device.quantity | fault-free /s | with errors /s | delivered | "
             "bus errors | reconfigurations |", "|---|---|---:|---:|---:|---:|---:|"]
    for board, (clean, faulty) in boards.items():
        glitchy = faulty[0]
        for (dev, ch), n in sorted(clean.valid.items(), key=lambda kv: (kv[0][0], kv[0][1].value)):
            got = glitchy.valid[(dev, ch)]
            lines.append(f"| {board} | {dev}.{ch.value} | {n / seconds:.1f} | "
                         f"{got / seconds:.1f} | {100 * got / n:.1f} % | "
                         f"{glitchy.bus_errors.get(dev, 0)} | "
                         f"{glitchy.reconfigurations.get(dev, 0)} |")
    return lines


def _ledger_cells(dev: str, quantity: Quantity, flights: list[Flight]) -> list[str]:
    """The ledger columns of ``dev``'s row for ``quantity`` (blank unless it is the
    device's accounted stream)."""
    kept = [f for f in flights if dev in f.ledgers and f.ledgers[dev][0] is quantity]
    if not kept:
        return [""] * 7
    counts: Counter[str] = Counter()
    for f in kept:
        counts.update(f.ledgers[dev][1])
    lost = ", ".join(f"{c.replace('_', ' ')} {counts['lost_' + c]}" for c in CAUSES
                     if counts["lost_" + c])
    balanced = all(c["delivered"] + sum(v for k, v in c.items() if k.startswith("lost_"))
                   == c["produced"] for _, c, _ in (f.ledgers[dev] for f in kept))
    chips = [f.within[dev][1] for f in kept]
    chip = "not recorded" if None in chips else str(sum(c for c in chips if c is not None))
    held = balanced and all(f.ledgers[dev][2] for f in kept)
    return [str(counts["produced"]), str(counts["delivered"]), lost or "0",
            str(counts[NOT_CONVERTED]), str(sum(f.within[dev][0] for f in kept)), chip,
            "yes" if held else "NO"]


def configured_table(boards: dict[str, tuple[Flight, list[Flight]]], seconds: float
                     ) -> list[str]:
    lines = ["| board | device.quantity | configured /s | delivered /s | of configured | "
             ">= 95 % | ledger: produced | delivered | lost (by cause) | slots not "
             "converted | produced within segments | the chip's count | delivered + lost = "
             "produced = the chip's count |", "|" + "---|" * 13]
    for board, (_, flights) in boards.items():
        keys = sorted({k for f in flights for k in f.configured_hz},
                      key=lambda k: (k[0], k[1].value))
        for dev, quantity in keys:
            configured = flights[0].configured_hz.get((dev, quantity), 0.0)
            delivered = min(f.valid[(dev, quantity)] / seconds for f in flights)
            share = delivered / configured
            serial = dev in flights[0].serial
            held = "serial: not held" if serial else ("yes" if share >= THRESHOLD else "NO")
            lines.append(f"| {board} | {dev}.{quantity.value} | {configured:g} | "
                         f"{delivered:.1f} | {100 * share:.1f} % | {held} | "
                         + " | ".join(_ledger_cells(dev, quantity, flights)) + " |")
    return lines


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--table", choices=sorted(BLOCKS), default="fault-free")
    parser.add_argument("--seconds", type=float, default=30.0)
    parser.add_argument("--rate", type=float, default=0.01)
    parser.add_argument("--seeds", type=int, default=3)
    parser.add_argument("--write", action="store_true",
                        help="fly what both tables need and replace both blocks")
    args = parser.parse_args(argv)
    registry = load_registry()
    tables = sorted(BLOCKS) if args.write else [args.table]
    # the fault-free table compares seed 1's flights; the configured table takes every seed
    seeds = args.seeds if "configured" in tables else 1
    boards: dict[str, tuple[Flight, list[Flight]]] = {}
    for board in sorted(bundled_profiles()):
        print(f"{board}...", file=sys.stderr, flush=True)
        clean = fly(registry, board, args.seconds, 0.0, 1) if "fault-free" in tables \
            else Flight()
        faulty = [fly(registry, board, args.seconds, args.rate, seed)
                  for seed in range(1, seeds + 1)]
        boards[board.removesuffix(".yaml")] = (clean, faulty)
    # the arguments that differ from the defaults, as the block's command names them
    given = [f"--{k}={v:g}" for k, v in vars(args).items()
             if k in ("seconds", "rate", "seeds") and v != parser.get_default(k)]
    for table in tables:
        command = generated_by(__file__, [f"--table={table}", *given])
        if table == "fault-free":
            head = (f"Generated by `{command}`: {args.seconds:g} s of `thermal` after "
                    f"{SETTLE_S:g} s, seed 1, `bus_errors` rate {args.rate:g} on every device.")
            rows = fault_free_table(boards, args.seconds)
        else:
            head = (f"Generated by `{command}`: `thermal`, {args.seconds:g} s after a "
                    f"{SETTLE_S:g} s start-up, uncalibrated, seeds 1..{args.seeds}, "
                    f"`bus_errors` rate {args.rate:g} on every device; delivered: the lowest "
                    "run's valid samples per second; ledger: the accounted stream's frames "
                    "summed over the runs.")
            rows = configured_table(boards, args.seconds)
        text = "\n".join([head, "", *rows])
        print(text)
        if args.write:
            write_block(*BLOCKS[table], text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
