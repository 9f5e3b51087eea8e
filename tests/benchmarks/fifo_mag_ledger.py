"""The seed paraglider's magnetometer ledger when its MAX21100 is read from the FIFO (plain
script; not collected by pytest).

Run:  .venv/bin/python -m tests.benchmarks.fifo_mag_ledger [--duration 20] [--frames 0,1,2,3,4,8]

The bundled seed-paraglider-vario with its MAX21100 set to ``read: fifo`` and each
``fifo_frames`` given (0: the profile as bundled, ``read: registers``), flying ``thermal``
(seed 1, the profile's sensor errors, no faults). The HMC5883L behind the MAX21100's
auto-read gets the master's copies of its fields from the MAX21100's MAG registers, which
the master overwrites at every accelerometer measurement: once read only with the FIFO
reads, a field copied between two reads was lost and the others stamped up to
``fifo_frames`` periods late; the driver now reads them every period between its FIFO
reads. Prints, per ``fifo_frames``, the magnetometer's frame ledger (produced, delivered,
lost and its causes) beside the measurements the emulated chip made over the ledger's
segments (``ChipEmulator.frames_between``): the fault matrix's check, which flies the
bundled profiles (register reads) only, and the SPI bus's transfers per simulated second
(the MAX21100's, its aux master's and the MS5611's).

docs/scripts/fifo_mag_ledger.py writes the table into docs/acquisition.md.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

from tests.benchmarks.bench_blocks import SEED, board_yaml
from tests.benchmarks.fault_matrix import ledgers_of

from imuhal.emulation import EmulatedBoard, open_emulated
from imuhal.plugins.manager import load_registry
from imuhal.profile.loader import load_profile

DURATION_S = 20.0
FRAMES = (0, 1, 2, 3, 4, 8)
"""The default flight and rows (``fifo_frames``; 0: read: registers)."""


def mag_ledger(fifo_frames: int, duration_s: float) -> dict[str, int]:
    """The magnetometer's ledger counts and the chip's measurements over its segments
    (``chip``), as the fault matrix compares them (``ledgers_of``), and the transfers on
    the board's SPI bus (``spi_transfers``: the MAX21100's, its aux master's one-shot
    reads of the HMC5883L and the MS5611's). ``fifo_frames`` 0: read: registers."""
    registry = load_registry()
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "board.yaml"
        path.write_text(board_yaml(fifo_frames or None, SEED))
        profile = load_profile(path, registry)
    with open_emulated(profile, registry, seed=1, scenario="thermal") as pipeline:
        spi = EmulatedBoard.of(pipeline).buses["spi0"]
        before = spi.transfers
        for _ in pipeline.events(duration_s):
            pass
        return {**ledgers_of(pipeline)["mag"], "spi_transfers": spi.transfers - before}


def table(frames: list[int], duration_s: float) -> list[str]:
    """The markdown table, a row per ``fifo_frames`` (0: read: registers)."""
    lines = ["| IMU read | produced (ledger) | delivered | lost (ledger) | lost: causes "
             "| the chip's count | ledger - chip | SPI transfers / s |",
             "| --- | ---: | ---: | ---: | --- | ---: | ---: | ---: |"]
    for n in frames:
        counts = mag_ledger(n, duration_s)
        measured = counts["chip"]
        lost = counts["produced"] - counts["delivered"]
        causes = ", ".join(f"{k.removeprefix('lost_')} {v}" for k, v in sorted(counts.items())
                           if k.startswith("lost_") and v) or "-"
        read = f"fifo, fifo_frames {n}" if n else "registers"
        lines.append(f"| {read} | {counts['produced']} | {counts['delivered']} | {lost} "
                     f"| {causes} | {measured} | {counts['produced'] - measured:+d} "
                     f"| {counts['spi_transfers'] / duration_s:.0f} |")
    return lines


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--duration", type=float, default=DURATION_S, help="simulated s per run")
    p.add_argument("--frames", default=",".join(map(str, FRAMES)),
                   help="comma-separated fifo_frames (0: read: registers)")
    args = p.parse_args(argv)
    print(f"seed-paraglider-vario, thermal {args.duration:g} s, seed 1: the "
          "magnetometer's ledger against the chip's measurements\n")
    lines = table([int(x) for x in args.frames.split(",")], args.duration)
    print("\n".join(lines))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
