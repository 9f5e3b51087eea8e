"""Polling and FIFO reading under host stalls: frames lost by cause and time-stamp errors
against the chip's own measurement instants (docs/acquisition.md).

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
Modes: ``poll`` (the profile as bundled) and ``fifo`` (the MPU-9250's ``read: fifo``; on the
seed-gps-vario the AK8963 then reads ``one-shot``, since the FIFO reader does not take a
slave auto-read yet).
"""

from __future__ import annotations

import argparse
import math
from bisect import bisect_right

from imuhal.core.samples import GyroSample
from imuhal.emulation import open_emulated
from imuhal.emulation.faults import HostStall
from imuhal.plugins.manager import Registry, load_registry
from imuhal.profile.bundled import bundled_profiles
from imuhal.profile.loader import load_profile
from imuhal.profile.model import BoardProfile

BOARDS = ("gy91", "seed-gps-vario")
STALLS_MS = (0.0, 20.0, 144.0, 300.0)
"""144 ms: 80 % of the MPU-9250's 512-byte FIFO in time with the reader's 14-byte frames
(36 frames, 180 ms at 200 Hz); 300 ms: longer than the FIFO."""


def _fifo(profile: BoardProfile) -> BoardProfile:
    """``profile`` with the MPU-9250 reading its FIFO (and the AK8963 one-shot if it was
    auto-read)."""
    devices = dict(profile.devices)
    imu = devices["imu"]
    devices["imu"] = imu.model_copy(update={"settings": {**imu.settings, "read": "fifo"}})
    mag = devices["mag"]
    if mag.settings.get("read") == "auto":
        devices["mag"] = mag.model_copy(update={"settings": {**mag.settings,
                                                             "read": "one-shot"}})
    return profile.model_copy(update={"devices": devices})


def run(registry: Registry, board: str, mode: str, stall_ms: float, seconds: float,
        seed: int) -> dict[str, float]:
    profile = load_profile(bundled_profiles()[f"{board}.yaml"], registry)
    if mode == "fifo":
        profile = _fifo(profile)
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
    print(f"`thermal` {args.seconds:g} s, seed {args.seed}, one host stall a second "
          "from 1 s on\n")
    print("| board | mode | stall | produced | delivered | lost: host stall | "
          "lost: FIFO overflow | lost: other | stamp error RMS | stamp error max |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    for board in BOARDS:
        for mode in ("poll", "fifo"):
            for stall_ms in STALLS_MS:
                r = run(registry, board, mode, stall_ms, args.seconds, args.seed)
                other = sum(v for k, v in r.items() if k.startswith("lost_")
                            and k not in ("lost_host_stall", "lost_fifo_overflow"))
                print(f"| {board} | {mode} | {stall_ms:g} ms | {r['produced']:.0f} | "
                      f"{r['delivered']:.0f} | {r['lost_host_stall']:.0f} | "
                      f"{r['lost_fifo_overflow']:.0f} | {other:.0f} | {r['rms_us']:.0f} us | "
                      f"{r['max_us']:.0f} us |")


if __name__ == "__main__":
    main()
