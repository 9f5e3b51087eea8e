"""Late polls (issues 25 and 26): the figures of docs/acquisition.md, "Late polls" (plain
script; not collected by pytest).

Run:  nice -n 10 .venv/bin/python -m tests.benchmarks.late_polls [--seconds 10]

Prints, on emulated boards with host stalls injected through imuhal.emulation.faults:

1. the auto-read copy: seed-gps-vario's AK8963 through the MPU-9250's slave 0, ideal chips
   in a fast turn, the host stalling 43.7 ms before a barometer poll every 0.25 s: how long
   after the measurement it carries each valid field is stamped (tests/support/late_polls);
2. the host-paced MS5611 in a lift at 4 m/s, stalls of 0.3 s before a magnetometer poll
   every 0.5 s: each valid pressure against the truth at its stamp;
3. the frame ledger against the chip's own count on every bundled board, ``--seconds`` of
   its profile's scenario with a stall of 43.7 ms before an IMU poll every 0.25 s (stalls
   at every phase of every device's period): per accounted device, produced, the chip's
   count over the ledger's segments, delivered and lost to host stalls.
"""

from __future__ import annotations

import argparse
import statistics
from collections.abc import Sequence

from tests.benchmarks.fault_matrix import ledgers_of
from tests.support.late_polls import auto_read_copy_lags, lift_pressure_errors_pa

from imuhal.emulation import open_emulated
from imuhal.emulation.faults import HostStall
from imuhal.plugins.manager import Registry, load_registry
from imuhal.profile.bundled import bundled_profiles
from imuhal.profile.loader import load_profile


def ledger_rows(registry: Registry, seconds: float) -> list[str]:
    rows = ["| board | device | produced | the chip's count | delivered | lost: host stall "
            "| lost: other |", "|---|---|---|---|---|---|---|"]
    for name, path in bundled_profiles().items():
        profile = load_profile(path, registry)
        stall = HostStall(device="imu", start_s=1.0, end_s=seconds, every_s=0.25,
                          stall_s=0.0437)
        with open_emulated(profile, registry, seed=1, faults=[stall]) as p:
            for _ in p.events(seconds):
                pass
            ledgers = ledgers_of(p)
        for device, c in ledgers.items():
            lost = {k[5:]: v for k, v in c.items() if k.startswith("lost_")}
            rows.append(f"| {name.removesuffix('.yaml')} | {device} | {c['produced']} | "
                        f"{c['chip']} | {c['delivered']} | {lost.pop('host_stall', 0)} | "
                        f"{sum(lost.values())} |")
    return rows


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--seconds", type=float, default=10.0)
    args = parser.parse_args(argv)
    registry = load_registry()
    lags = auto_read_copy_lags(registry)
    ms = [n / 1e6 for n in lags.lags_ns]
    print(f"auto-read copies: {lags.fields} valid fields, {len(ms)} told apart; stamped "
          f"{min(ms):.2f} to {max(ms):.2f} ms after their measurement "
          f"(median {statistics.median(ms):.2f})")
    off = lift_pressure_errors_pa(registry)
    rms = statistics.fmean(x * x for x in off) ** 0.5
    print(f"MS5611 in the lift: {len(off)} valid pressures, off the truth at their stamps by "
          f"{rms:.2f} Pa RMS, {max(off):.2f} Pa at most")
    print("\n".join(ledger_rows(registry, args.seconds)))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
