"""GNSS heights and stale navigation (docs/reliability.md, ``gnss-heights-stale`` block):
what the vertical position rule catches of the same flip in both heights, at the receiver's
rates and accuracies, and what a receiver restarted with stale navigation data gives.

Two tables, on the seed GPS vario flying its ``thermal`` (seed 1):

* **both heights**: from 5 s on, one NAV-PVT every 2 s gets bit 7 of the second byte of
  height and of hMSL flipped (``corrupt_byte`` twice, 4 bytes apart: the Fletcher checksum
  holds), in the epochs where that bit is the same in both heights, so both move by the
  same 32.768 m and the geoid separation holds. Receivers: 5 Hz at the emulated receiver's
  vAcc of 4 m and at 8 m (a poor sky), 1 Hz at 4 m, with the profile's default 10 g and
  with 4 g (``max_acceleration_m_s2``). Each hit epoch is compared with the same epoch of
  the clean flight (docs/scripts/gnss_integrity.py): flagged or dropped (detected), or
  valid and moved. The gate column is the driver's vertical rule's bound for equal velDs at
  the rate (imuhal_chips.gnss.integrity): what a flip must exceed to be caught by the
  receiver's own data; the pipeline's cross-check against the barometer
  (imuhal.pipeline.crosscheck) catches what passes it (flagged CONTRADICTED alone), and the
  last column counts its false alarms in the clean flight.
* **stale navigation**: ``stale_navigation`` (each ``time`` mode), 2 s every 20 s from
  20 s on, NAV-PVT at 5 Hz and NMEA at 1 Hz: the epochs the receiver sent stale (a fix
  repeating the solution before the window), how many were flagged STALE, how many of them
  were valid, and how many fresh epochs of the flight were flagged STALE (false alarms).

Usage: ``docs/scripts/gnss_heights_and_stale.py [--seconds S] [--write]`` (prints the
block; ``--write`` replaces it in docs/reliability.md).
"""

from __future__ import annotations

import argparse
import math
import sys
from dataclasses import dataclass, field

from docblock import ROOT, generated_by, write_block
from gnss_integrity import FIRST_HIT_S, H_MSL, HEIGHT, PAYLOAD, Flight, Pair, _hit_epochs

from imuhal.core.samples import PositionSample, SampleFlag
from imuhal.emulation import open_emulated
from imuhal.emulation.faults import CorruptByte, FaultSpec, StaleNavigation
from imuhal.plugins.manager import Registry, load_registry
from imuhal.profile.bundled import bundled_profiles
from imuhal.profile.loader import parse_profile, read_profile_text
from imuhal.profile.model import BoardProfile
from imuhal_chips.gnss.emulator import GnssErrorModel
from imuhal_chips.gnss.integrity import (
    GATE_SIGMAS,
    height_error_change_m,
    vertical_manoeuvre_m,
)

BOARD = "seed-gps-vario.yaml"
PAGE = ROOT / "docs" / "reliability.md"
BLOCK = "gnss-heights-stale"
SCENARIO = "thermal"
SEED = 1
UBX = ("      protocol: ubx\n      baud_rates: [9600, 115200]\n      rate_hz: 5\n"
       "      messages: [NAV-PVT]\n")
GEOID_SEPARATION_M = 48.0
"""The emulated receiver's (GnssErrorModel's default): height = hMSL + this."""
SPEED_ACCURACY_M_S = 0.15
STALE_EVERY_S, STALE_FOR_S, STALE_FROM_S = 20.0, 2.0, 20.0
HIT_EVERY_S = 2.0
"""One frame hit every 2 s: at 1 Hz a frame a second would hit every epoch, a lasting
offset (which the three-epoch rule takes as a new level), not one wrong epoch."""


@dataclass(frozen=True)
class Receiver:
    """One receiver set-up of the heights table."""

    rate_hz: float
    vertical_accuracy_m: float
    max_acceleration_m_s2: float

    @property
    def name(self) -> str:
        return (f"{self.rate_hz:g} Hz, vAcc {self.vertical_accuracy_m:g} m, "
                f"{self.max_acceleration_m_s2 / 9.80665:.0f} g")

    def gate_m(self) -> float:
        """The vertical rule's bound between two epochs with equal velDs."""
        dt_s = 1.0 / self.rate_hz
        speed_var = 2 * SPEED_ACCURACY_M_S**2 * (dt_s / 2.0) ** 2
        sigma = math.sqrt(height_error_change_m(self.vertical_accuracy_m, dt_s) ** 2
                          + speed_var)
        return GATE_SIGMAS * sigma + vertical_manoeuvre_m(self.max_acceleration_m_s2, dt_s,
                                                          0.0)


@dataclass
class Fixes(Flight):
    """A flight's valid fixes by UTC (Flight) and every fix in order, flagged or not."""

    all_fixes: list[PositionSample] = field(default_factory=list)


RECEIVERS = (Receiver(5.0, 4.0, 100.0), Receiver(5.0, 8.0, 100.0),
             Receiver(1.0, 4.0, 100.0), Receiver(1.0, 4.0, 4 * 9.80665))


def profile_of(registry: Registry, *, rate_hz: float = 5.0, nmea: bool = False,
               max_acceleration_m_s2: float = 100.0) -> BoardProfile:
    """The seed GPS vario with its receiver at ``rate_hz`` (NAV-PVT, or NMEA's four
    sentences) and its driver's acceleration limit."""
    text = read_profile_text(bundled_profiles()[BOARD])
    assert UBX in text, "the seed GPS vario's receiver settings changed"
    messages = "[RMC, VTG, GGA, GSA]" if nmea else "[NAV-PVT]"
    text = text.replace(UBX, f"      protocol: {'nmea' if nmea else 'ubx'}\n"
                             "      baud_rates: [9600, 115200]\n"
                             f"      rate_hz: {rate_hz:g}\n      messages: {messages}\n"
                             f"      max_acceleration_m_s2: {max_acceleration_m_s2}\n")
    return parse_profile(text, f"{BOARD} at {rate_hz:g} Hz", registry)


def fly(profile: BoardProfile, registry: Registry, seconds: float,
        faults: list[FaultSpec], model: GnssErrorModel | None = None) -> Fixes:
    """Valid fixes by UTC (ms) and every fix with a fix type, in order."""
    out = Fixes()
    with open_emulated(profile, registry, scenario=SCENARIO, seed=SEED, faults=faults,
                       calibrated=False) as p:
        if model is not None:
            p.board.emulators["gps"].use_model(model)  # type: ignore[attr-defined]  # the GNSS emulator
        for e in p.events(seconds):
            if isinstance(e, PositionSample) and e.fix_type != 0:
                out.epochs += 1
                out.all_fixes.append(e)
                if e.valid and e.utc_s is not None:
                    out.fixes[round(e.utc_s, 3)] = e
    return out


def _same_bit_15(fix: PositionSample) -> bool:
    """Whether bit 7 of the second byte (bit 15) is the same in hMSL and height (mm)."""
    h_msl_mm = round(fix.height_m * 1000)
    height_mm = round((fix.height_m + GEOID_SEPARATION_M) * 1000)
    return (h_msl_mm >> 15 & 1) == (height_mm >> 15 & 1)


def heights_hits(clean: Fixes, seconds: float, rate_hz: float
                 ) -> tuple[list[FaultSpec], dict[float, Pair]]:
    """Both heights' second bytes hit in one frame every HIT_EVERY_S from FIRST_HIT_S,
    where the flip moves both the same way."""
    faults: list[FaultSpec] = []
    plan: dict[float, Pair] = {}
    period_s = 1.0 / rate_hz
    for utc, fix in sorted(clean.fixes.items()):
        t_s = fix.t_ns / 1e9
        if t_s < FIRST_HIT_S or t_s > seconds - 1.0 or round(utc % HIT_EVERY_S, 1) != 0.0 \
                or not _same_bit_15(fix):
            continue
        flips: Pair = ((HEIGHT + 1, 0x80), (H_MSL + 1, 0x80))
        # the epoch's frame is the first thing received after its epoch time + 50 ms
        start_s = math.floor(t_s / period_s) * period_s + 0.05
        faults += [CorruptByte(device="gps", start_s=start_s, byte=PAYLOAD + k, mask=mask)
                   for k, mask in flips]
        plan[utc] = flips
    return faults, plan


def heights_row(registry: Registry, receiver: Receiver, seconds: float) -> str:
    profile = profile_of(registry, rate_hz=receiver.rate_hz,
                         max_acceleration_m_s2=receiver.max_acceleration_m_s2)
    model = GnssErrorModel(vertical_accuracy_m=receiver.vertical_accuracy_m)
    print(f"heights, {receiver.name}: clean...", file=sys.stderr, flush=True)
    clean = fly(profile, registry, seconds, [], model)
    faults, plan = heights_hits(clean, seconds, receiver.rate_hz)
    print(f"heights, {receiver.name}: {len(plan)} frames hit...", file=sys.stderr, flush=True)
    hit = fly(profile, registry, seconds, faults, model)
    detected, errors, others = _hit_epochs(clean, hit, plan)
    worst_v = max((v for _, v, _, _ in errors), default=0.0)
    by_baro = sum(1 for e in hit.all_fixes if e.utc_s is not None and round(e.utc_s, 3) in plan
                  and e.flags == SampleFlag.CONTRADICTED)
    false_alarms = sum(1 for e in clean.all_fixes if e.flags & SampleFlag.CONTRADICTED)
    return (f"| {receiver.name} | {receiver.gate_m():.1f} | {len(plan)} | {detected} | "
            f"{by_baro} | {len(errors)} | {worst_v:.3f} | {others} | {false_alarms} |")


def stale_windows(seconds: float, time: str) -> list[FaultSpec]:
    out: list[FaultSpec] = []
    start = STALE_FROM_S
    while start + STALE_FOR_S < seconds - 1.0:
        out.append(StaleNavigation(device="gps", start_s=start, end_s=start + STALE_FOR_S,
                                   time=time))  # type: ignore[arg-type]  # "repeated" or "unresolved"
        start += STALE_EVERY_S
    return out


def stale_row(registry: Registry, nmea: bool, time: str, seconds: float) -> str:
    """Epochs sent stale (a fix repeating the last solution before its window), flagged
    STALE, valid; fresh fixes flagged STALE."""
    rate_hz = 1.0 if nmea else 5.0
    profile = profile_of(registry, rate_hz=rate_hz, nmea=nmea)
    faults = stale_windows(seconds, time)
    name = f"{'NMEA' if nmea else 'NAV-PVT'} at {rate_hz:g} Hz, time {time}"
    print(f"stale, {name}...", file=sys.stderr, flush=True)
    flight = fly(profile, registry, seconds, faults)
    sent_stale = flagged = valid = false_alarms = 0
    last: tuple[float, float, float] | None = None
    for fix in flight.all_fixes:
        position = (fix.latitude_deg, fix.longitude_deg, fix.height_m)
        stale = position == last  # the emulated receiver's solutions never repeat otherwise
        flagged_stale = bool(fix.flags & SampleFlag.STALE)
        sent_stale += stale
        flagged += stale and flagged_stale
        valid += stale and fix.valid
        false_alarms += flagged_stale and not stale
        if not stale:
            last = position
    return (f"| {name} | {len(faults)} | {sent_stale} | {flagged} | {valid} | "
            f"{false_alarms} |")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--seconds", type=float, default=300.0)
    parser.add_argument("--write", action="store_true")
    args = parser.parse_args(argv)
    registry = load_registry()
    height_rows = [heights_row(registry, r, args.seconds) for r in RECEIVERS]
    stale_rows = [stale_row(registry, nmea, time, args.seconds)
                  for nmea in (False, True) for time in ("repeated", "unresolved")
                  if not (nmea and time == "unresolved")]
    given = [f"--seconds={args.seconds:g}"] if args.seconds != 300.0 else []
    text = "\n".join([
        f"Generated by `{generated_by(__file__, given)}`: seed-gps-vario flying "
        f"`{SCENARIO}`, seed {SEED}, {args.seconds:g} s each.",
        "",
        f"| receiver, one frame every {HIT_EVERY_S:g} s from {FIRST_HIT_S:g} s hit in bit 7 "
        "of the second "
        "byte of height and of hMSL (both 32.768 m, geoid separation kept) | the driver's "
        "vertical gate (m) | frames hit | detected (flagged or dropped) | of them only by the "
        "barometer (CONTRADICTED) | valid | largest vertical error left valid (m) | other "
        "fixes changed | clean flight: fixes flagged CONTRADICTED |",
        "|---|---|---|---|---|---|---|---|---|",
        *height_rows,
        "",
        f"| `stale_navigation`, {STALE_FOR_S:g} s every {STALE_EVERY_S:g} s from "
        f"{STALE_FROM_S:g} s | windows | fixes sent stale | flagged STALE | valid | fresh "
        "fixes flagged STALE |",
        "|---|---|---|---|---|---|",
        *stale_rows,
    ])
    print(text)
    if args.write:
        write_block(PAGE, BLOCK, text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
