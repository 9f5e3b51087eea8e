"""Delivered share of the *configured* samples of every device of every bundled board at 1 %
bus errors, and the frame ledger's balance (docs/acquisition.md, "At 1 % bus errors").

Usage::

    .venv/bin/python docs/scripts/delivery_of_configured.py [--seconds S] [--rate R]
        [--seeds N]

Each bundled board flies ``thermal`` for ``--seconds`` simulated seconds after a 1 s start-up,
uncalibrated, with ``bus_errors`` of probability ``--rate`` on every device (imuhal.emulation.
faults, as a profile's ``faults`` would), once per seed 1..``--seeds``. Per device and
quantity it prints the configured rate (the stream spec's ``rate_hz``, read back from the
chip's registers: what the profile asked for), the valid samples per second delivered after
the start-up, their share of the configured rate (the lowest over the seeds), and, for the
device's accounted stream (imuhal.pipeline.accounting), produced, delivered and lost by
cause with whether delivered + lost = produced held in every run, and the ledger's produced
frames within its segments (produced less the reset slots between segments) beside what the
chip's own record of its measurements (the emulator's ``measured_ns``) gives over the same
segments: the two should be equal. Serial devices (the GNSS
receiver) are listed but not held to 95 %: a UART has no retry, so ``bus_errors`` (each byte
corrupted or dropped with probability ``rate``) leave 0.99^100 of a 100-byte frame, which the
checksum then rejects (docs/reliability.md).
"""

from __future__ import annotations

import argparse
import signal
from collections import Counter
from dataclasses import dataclass, field

from imuhal.bus.base import BusKind
from imuhal.core.samples import Quantity, Sample
from imuhal.emulation import open_emulated
from imuhal.emulation.faults import BusErrors
from imuhal.pipeline.accounting import CAUSES
from imuhal.plugins.manager import Registry, load_registry
from imuhal.profile.bundled import bundled_profiles
from imuhal.profile.loader import load_profile

SETTLE_S = 1.0
THRESHOLD = 0.95


@dataclass
class Row:
    """One device quantity over the runs."""

    configured_hz: float = 0.0
    shares: list[float] = field(default_factory=list)
    delivered_hz: list[float] = field(default_factory=list)
    serial: bool = False
    ledger: Counter[str] = field(default_factory=Counter)
    balanced: bool = True
    accounted: bool = False
    chip: int | None = None
    """What the chip's own record of its measurements gives over the ledger's segments
    (None: its emulator keeps none)."""


def run(registry: Registry, board: str, seconds: float, rate: float, seed: int,
        rows: dict[tuple[str, str], Row]) -> None:
    """One flight of ``board``: adds its figures to ``rows`` (by device, quantity)."""
    profile = load_profile(bundled_profiles()[board], registry)
    devices = [n for n, d in profile.devices.items() if d.enabled]
    faults = [BusErrors(device=d, rate=rate) for d in devices]
    counts: Counter[tuple[str, Quantity]] = Counter()
    with open_emulated(profile, registry, seed=seed, faults=faults, calibrated=False) as p:
        start_ns = p.clock.now_ns() + round(SETTLE_S * 1e9)
        for e in p.events(seconds + SETTLE_S):
            if isinstance(e, Sample) and e.valid and e.t_ns >= start_ns:
                counts[(e.device, e.channel)] += 1
        for name, dev in p.devices.items():
            serial = dev.driver.link.kind is BusKind.SERIAL
            ledger = dev.ledger
            for spec in p.streams.get(name, ()):
                if spec.rate_hz is None or spec.rate_hz <= 0:
                    continue
                row = rows.setdefault((name, spec.quantity.value), Row())
                row.configured_hz = spec.rate_hz
                row.serial = serial
                got = counts[(name, spec.quantity)] / seconds
                row.delivered_hz.append(got)
                row.shares.append(got / spec.rate_hz)
                if ledger is not None and ledger.channel is spec.quantity:
                    row.accounted = True
                    row.ledger.update(ledger.counts())
                    row.balanced &= ledger.delivered + sum(ledger.lost.values()) == \
                        ledger.produced
                    chip = p.board.emulators[name]
                    if len(chip.measured_ns):
                        row.chip = (row.chip or 0) + sum(chip.frames_between(a, b)
                                                         for a, b, _ in ledger.all_segments())


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--seconds", type=float, default=30.0)
    parser.add_argument("--rate", type=float, default=0.01)
    parser.add_argument("--seeds", type=int, default=3)
    args = parser.parse_args()
    # figures of emulated time must not depend on the host's load: the pipeline's wall-clock
    # deadline on driver calls (imuhal.pipeline.containment.Watchdog, a live-run guard) does
    # not arm while SIGALRM is taken by someone else, as here
    signal.signal(signal.SIGALRM, signal.SIG_IGN)
    registry = load_registry()
    print(f"`thermal`, {args.seconds:g} s after a {SETTLE_S:g} s start-up, bus_errors rate "
          f"{args.rate:g} on every device, seeds 1..{args.seeds}; delivered: valid samples "
          "per second (the lowest run's share of the configured rate); ledger: the accounted "
          "stream's frames summed over the runs\n")
    print("| board | device.quantity | configured /s | delivered /s | of configured | "
          ">= 95 % | ledger: produced | delivered | lost (by cause) | delivered + lost = "
          "produced | within segments: ledger | the chip's count |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|")
    for board in sorted(bundled_profiles()):
        rows: dict[tuple[str, str], Row] = {}
        for seed in range(1, args.seeds + 1):
            run(registry, board, args.seconds, args.rate, seed, rows)
        for (dev, quantity), row in sorted(rows.items()):
            low = min(row.shares)
            held = "serial: not held" if row.serial else ("yes" if low >= THRESHOLD else "NO")
            ledger = ["", "", "", "", "", ""]
            if row.accounted:
                lost = ", ".join(f"{c.replace('_', ' ')} {row.ledger['lost_' + c]}"
                                 for c in CAUSES if row.ledger["lost_" + c])
                ledger = [str(row.ledger["produced"]), str(row.ledger["delivered"]),
                          lost or "0", "yes" if row.balanced else "NO",
                          str(row.ledger["produced"] - row.ledger["lost_reset"]),
                          "not recorded" if row.chip is None else str(row.chip)]
            print(f"| {board.removesuffix('.yaml')} | {dev}.{quantity} | "
                  f"{row.configured_hz:g} | {min(row.delivered_hz):.1f} | {100 * low:.1f} % | "
                  f"{held} | " + " | ".join(ledger) + " |")


if __name__ == "__main__":
    main()
