"""Polling under host stalls: frames lost by cause and time-stamp errors against the chip's
own measurement instants (docs/acquisition.md).

Usage::

    .venv/bin/python docs/scripts/acquisition_table.py [--seconds S] [--seed N]

Each MPU-9250 board (gy91, seed-gps-vario) flies ``thermal`` for ``--seconds`` simulated
seconds (uncalibrated, seed ``--seed``), with a ``host_stall`` fault (imuhal.emulation.faults)
of each length in STALLS_MS once a second from 1 s on, and once without. The MPU-9250
emulator measures on its own clock (issue 25 item 1) and records its measurement instants,
so each valid IMU sample's time stamp is compared with the instant of the frame it carries
(the chip's latest measurement at or before the stamp). Printed as a Markdown table: frames
the chip produced over the run (the frame ledger, imuhal.pipeline.accounting), delivered,
lost by cause, and the stamp error (stamp minus chip instant) RMS and max in microseconds.
Acquisition mode: polling (the only one so far; FIFO and data-ready modes are issue 25
items 2 and 3).
"""

from __future__ import annotations

import argparse
import math
from bisect import bisect_right

from imuhal.core.samples import GyroSample
from imuhal.emulation import open_emulated
from imuhal.emulation.faults import HostStall
from imuhal.plugins.manager import Registry, load_registry
from imuhal.profile.loader import load_profile
from imuhal.profiles_dir import bundled_profiles

BOARDS = ("gy91", "seed-gps-vario")
STALLS_MS = (0.0, 20.0, 92.0)
"""92 ms: 80 % of the MPU-9250's 512-byte FIFO in time with 22-byte frames (accel, temperature,
gyro and the AK8963's 8 bytes) at 200 Hz (23 frames, 115 ms)."""


def run(registry: Registry, board: str, stall_ms: float, seconds: float, seed: int
        ) -> dict[str, float]:
    profile = load_profile(bundled_profiles()[f"{board}.yaml"], registry)
    faults = [HostStall(device="imu", start_s=1.0, every_s=1.0, stall_s=stall_ms / 1e3)] \
        if stall_ms else []
    with open_emulated(profile, registry, scenario="thermal", seed=seed, faults=faults,
                       calibrated=False) as p:
        stamps = [e.t_ns for e in p.events(seconds)
                  if isinstance(e, GyroSample) and e.device == "imu" and e.valid]
        frames = p.summary().frames["imu"]
        instants = p.board.emulators["imu"].measured_ns
    errors_us = [(t - instants[bisect_right(instants, t) - 1]) / 1e3 for t in stamps]
    return {**frames,
            "rms_us": math.sqrt(sum(e * e for e in errors_us) / len(errors_us)),
            "max_us": max(errors_us)}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--seconds", type=float, default=60.0)
    parser.add_argument("--seed", type=int, default=1)
    args = parser.parse_args()
    registry = load_registry()
    print(f"polling, `thermal` {args.seconds:g} s, seed {args.seed}, one host stall a second "
          "from 1 s on\n")
    print("| board | stall | produced | delivered | lost: host stall | lost: other | "
          "stamp error RMS | stamp error max |")
    print("|---|---|---|---|---|---|---|---|")
    for board in BOARDS:
        for stall_ms in STALLS_MS:
            r = run(registry, board, stall_ms, args.seconds, args.seed)
            other = sum(v for k, v in r.items()
                        if k.startswith("lost_") and k != "lost_host_stall")
            print(f"| {board} | {stall_ms:g} ms | {r['produced']:.0f} | {r['delivered']:.0f} | "
                  f"{r['lost_host_stall']:.0f} | {other:.0f} | {r['rms_us']:.0f} us | "
                  f"{r['max_us']:.0f} us |")


if __name__ == "__main__":
    main()
