"""Delivered fraction of every device of every bundled board under transient bus errors.

Usage::

    .venv/bin/python docs/scripts/delivery_under_bus_errors.py [--seconds S] [--rate R]
        [--seed N]

Each bundled board is emulated twice for ``--seconds`` simulated seconds (``thermal``,
uncalibrated, seed ``--seed``): fault-free, and with ``bus_errors`` of probability ``--rate``
on every device (imuhal.emulation.faults, as a profile's ``faults`` would). It prints, per
device and quantity, the valid samples per second of both runs after a 1 s start-up, the
delivered fraction (faulty over fault-free), the device's bus errors and the driver's
reconfigurations, as a Markdown table (docs/reliability.md, "Why the MPU-9250 boards lost a
quarter of their samples").
"""

from __future__ import annotations

import argparse
from collections import Counter

from imuhal.core.samples import Quantity, Sample
from imuhal.emulation import open_emulated
from imuhal.emulation.faults import BusErrors
from imuhal.plugins.manager import Registry, load_registry
from imuhal.profile.bundled import bundled_profiles
from imuhal.profile.loader import load_profile

SETTLE_S = 1.0


def run(registry: Registry, board: str, seconds: float, rate: float, seed: int
        ) -> tuple[Counter[tuple[str, Quantity]], dict[str, int], dict[str, int]]:
    """Valid samples per (device, quantity) after SETTLE_S, bus errors and reconfigurations
    per device."""
    profile = load_profile(bundled_profiles()[board], registry)
    devices = [n for n, d in profile.devices.items() if d.enabled]
    faults = [BusErrors(device=d, rate=rate) for d in devices] if rate else []
    counts: Counter[tuple[str, Quantity]] = Counter()
    with open_emulated(profile, registry, seed=seed, faults=faults, calibrated=False) as p:
        start_ns = p.clock.now_ns() + round(SETTLE_S * 1e9)
        for e in p.events(seconds + SETTLE_S):
            if isinstance(e, Sample) and e.valid and e.t_ns >= start_ns:
                counts[(e.device, e.channel)] += 1
        summary = p.summary()
    reconfigurations = {n: c["reconfigurations"] for n, c in summary.driver.items()}
    return counts, summary.bus_errors, reconfigurations


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--seconds", type=float, default=30.0)
    parser.add_argument("--rate", type=float, default=0.01)
    parser.add_argument("--seed", type=int, default=1)
    args = parser.parse_args()
    registry = load_registry()
    print(f"{args.seconds:g} s of `thermal` after {SETTLE_S:g} s, seed {args.seed}, "
          f"bus_errors rate {args.rate:g} on every device\n")
    print("| board | device.quantity | fault-free /s | with errors /s | delivered | "
          "bus errors | reconfigurations |")
    print("|---|---|---|---|---|---|---|")
    for board in sorted(bundled_profiles()):
        clean, _, _ = run(registry, board, args.seconds, 0.0, args.seed)
        glitchy, errors, reconf = run(registry, board, args.seconds, args.rate, args.seed)
        for (dev, ch), n in sorted(clean.items(), key=lambda kv: (kv[0][0], kv[0][1].value)):
            got = glitchy[(dev, ch)]
            print(f"| {board.removesuffix('.yaml')} | {dev}.{ch.value} | "
                  f"{n / args.seconds:.1f} | {got / args.seconds:.1f} | {100 * got / n:.1f} % | "
                  f"{errors.get(dev, 0)} | {reconf.get(dev, 0)} |")


if __name__ == "__main__":
    main()
