"""GNSS integrity beyond the checksum (docs/reliability.md, ``gnss-integrity`` block): how
close honest epochs come to the integrity checks' bounds on a clean line, and what pairs of
flipped bits that the UBX checksum cannot see do to the positions.

Two parts, on the seed GPS vario (u-blox NAV-PVT at 5 Hz) flying each scenario:

* **clean**: the epochs, the first ones refused until the first fix was confirmed (by
  design: CONFIRM - 1), the epochs flagged IMPLAUSIBLE after them (a false alarm each), and
  per rule the largest residual over its bound among the epochs that passed (below 1
  passes; the margin to a false alarm); the same for the pipeline's cross-check of the
  heights and velD against the barometer (imuhal.pipeline.crosscheck: values flagged
  CONTRADICTED, and its two residuals);
* **flips**: from 5 s on, one NAV-PVT a second gets bit 7 flipped in two payload bytes an
  even number of bytes apart (``corrupt_byte`` twice; UBX's Fletcher checksum holds), one of
  them a byte of lon, lat, height or hMSL, the other any byte of the same parity (seeded).
  Each hit frame's epoch is compared with the same epoch of the clean flight: its position
  or its velocity flagged or dropped (detected), or valid. A valid one that differs from the
  receiver's is counted with its displacement.
* **what the checks cannot see** (``thermal`` only), the same way, one class of pair per
  flight: the same bit 7 flip in one byte of height and the same byte of hMSL (the geoid
  separation holds); velD's two lower bytes hit by bit 7 (a partner of the same parity) or
  bit 6 (a partner a multiple of 4 bytes away, which the checksum misses when the two bits
  move opposite ways); nano's two lower bytes hit by bit 7 (a time error under 2 ms). A
  valid epoch that differs from the receiver's is counted with its position, velocity and
  time-stamp errors; "other fixes changed" counts valid fixes of the other epochs that
  differ (a time stamp moved by the driver's time mapping).

Usage: ``docs/scripts/gnss_integrity.py [--seconds S] [--write]`` (prints the block;
``--write`` replaces it in docs/reliability.md).
"""

from __future__ import annotations

import argparse
import math
import random
import sys
from collections.abc import Callable
from dataclasses import dataclass, field

from docblock import ROOT, generated_by, write_block

from imuhal.core.samples import PositionSample, SampleFlag, VelocitySample
from imuhal.emulation import open_emulated
from imuhal.emulation.faults import CorruptByte
from imuhal.plugins.manager import Registry, load_registry
from imuhal.profile.bundled import bundled_profiles
from imuhal.profile.loader import load_profile
from imuhal_chips.gnss.integrity import UNCONFIRMED, Epoch, local_offset_m

BOARD = "seed-gps-vario.yaml"
SCENARIOS = ("thermal", "rc-flight")
PAGE = ROOT / "docs" / "reliability.md"
BLOCK = "gnss-integrity"
FIRST_HIT_S = 5.0
PAYLOAD = 6
"""Sync characters, class, id and length before a UBX payload."""
POSITION_BYTES = tuple(range(24, 40))
"""NAV-PVT payload bytes of lon, lat, height and hMSL (u-blox M8 protocol, I4 each)."""
HEIGHT, H_MSL, VEL_D, NANO = 32, 36, 56, 16
"""NAV-PVT payload offsets of height, hMSL, velD and nano (I4 each)."""
PAYLOAD_BYTES = 92
RULES = ("horizontal position", "vertical position", "geoid separation", "time")
SAME_TIME_NS = 1000
"""Fixes of two flights at the same UTC whose stamps differ by less than this are at the same
time (a flip in nano's lowest byte moves the driver's time mapping by 128 ns)."""


Pair = tuple[tuple[int, int], tuple[int, int]]
"""Two (payload byte, mask) flips in one frame."""


@dataclass
class Flight:
    """What one flight gave: valid fixes by UTC and valid velocities by time stamp, epochs,
    flags and the watch's margins."""

    fixes: dict[float, PositionSample] = field(default_factory=dict)
    velocities: dict[int, VelocitySample] = field(default_factory=dict)
    epochs: int = 0
    implausible: int = 0
    contradicted: int = 0
    """Fixes and velocities flagged CONTRADICTED after the first fix was confirmed."""
    cross_ratio: dict[str, float] = field(default_factory=dict)
    refused: dict[str, int] = field(default_factory=dict)
    worst_ratio: dict[str, float] = field(default_factory=dict)


def fly(registry: Registry, scenario: str, seconds: float,
        faults: list[CorruptByte] | None = None) -> Flight:
    profile = load_profile(bundled_profiles()[BOARD], registry)
    out = Flight()
    with open_emulated(profile, registry, scenario=scenario, seed=1, faults=faults or [],
                       calibrated=False) as p:
        for e in p.events(seconds):
            if isinstance(e, PositionSample) and not e.flags & SampleFlag.STALE:
                out.epochs += 1
                if e.valid and e.utc_s is not None:
                    # by the ms: a flip in nano's low byte moves utc_s by 128 ns
                    out.fixes[round(e.utc_s, 3)] = e
            if isinstance(e, VelocitySample) and e.valid:
                out.velocities[e.t_ns] = e
            if isinstance(e, PositionSample) and e.flags & SampleFlag.IMPLAUSIBLE and \
                    out.fixes:
                out.implausible += 1  # after the first fix was confirmed: a false alarm
            if isinstance(e, PositionSample | VelocitySample) and out.fixes and \
                    e.flags & SampleFlag.CONTRADICTED:
                out.contradicted += 1
        watch = p.devices["gps"].driver.epoch_watch  # type: ignore[attr-defined]
        out.refused = dict(watch.refused)
        out.worst_ratio = dict(watch.worst_ratio)
        assert p.vertical_check is not None
        out.cross_ratio = dict(p.vertical_check.stats.worst_ratio)
    return out


def position_pair(rng: random.Random) -> Pair:
    """Bit 7 of a byte of lon, lat, height or hMSL, and of any byte of the same parity."""
    i = rng.choice(POSITION_BYTES)
    j = rng.choice([k for k in range(i % 2, PAYLOAD_BYTES, 2) if k != i])
    return (i, 0x80), (j, 0x80)


def heights_pair(rng: random.Random) -> Pair:
    """Bit 7 of the same byte of height and of hMSL (4 bytes apart: the checksum holds)."""
    k = rng.randrange(4)
    return (HEIGHT + k, 0x80), (H_MSL + k, 0x80)


def vel_d_pair(rng: random.Random) -> Pair:
    """Bit 7 of velD's lowest two bytes and of any byte of the same parity, or bit 6 and a
    byte a multiple of 4 away (the checksum misses it when the two bits move opposite ways:
    then CK_A is unchanged and CK_B moves by 64 times a multiple of 4)."""
    i = VEL_D + rng.randrange(2)
    mask = rng.choice((0x80, 0x40))
    step = 2 if mask == 0x80 else 4
    j = rng.choice([k for k in range(i % step, PAYLOAD_BYTES, step) if k != i])
    return (i, mask), (j, mask)


def nano_pair(rng: random.Random) -> Pair:
    """Bit 7 of nano's lowest two bytes (128 ns, 32.8 us) and of a byte of the same parity."""
    i = NANO + rng.randrange(2)
    j = rng.choice([k for k in range(i % 2, PAYLOAD_BYTES, 2) if k != i])
    return (i, 0x80), (j, 0x80)


def hits(clean: Flight, seconds: float, rng: random.Random,
         pair: Callable[[random.Random], Pair] = position_pair
         ) -> tuple[list[CorruptByte], dict[float, Pair]]:
    """One pair of flips (``pair``) in one frame a second from FIRST_HIT_S: the faults, and
    the hit epochs' UTC with the two flips."""
    faults: list[CorruptByte] = []
    plan: dict[float, Pair] = {}
    for utc, fix in sorted(clean.fixes.items()):
        t_s = fix.t_ns / 1e9
        if t_s < FIRST_HIT_S or t_s > seconds - 1.0:
            continue
        # the epoch's frame is the first thing received after its epoch time + 50 ms
        epoch_s = round(utc % 1.0, 1)
        if epoch_s != 0.0:
            continue
        flips = pair(rng)
        start_s = math.floor(t_s * 5) / 5 + 0.05
        faults += [CorruptByte(device="gps", start_s=start_s, byte=PAYLOAD + k, mask=mask)
                   for k, mask in flips]
        plan[utc] = flips
    return faults, plan


def _as_epoch(fix: PositionSample) -> Epoch:
    return Epoch(t_ns=fix.t_ns, latitude_deg=fix.latitude_deg,
                 longitude_deg=fix.longitude_deg, height_msl_m=fix.height_m,
                 velocity_ned_m_s=None, horizontal_accuracy_m=0.0, vertical_accuracy_m=None,
                 speed_accuracy_m_s=0.0)


def _same(sent: PositionSample | None, got: PositionSample) -> bool:
    """Whether ``got`` is the fix the receiver sent as ``sent``, at the same time."""
    return sent is not None and abs(sent.t_ns - got.t_ns) < SAME_TIME_NS and \
        (sent.latitude_deg, sent.longitude_deg, sent.height_m) == \
        (got.latitude_deg, got.longitude_deg, got.height_m)


def _hit_epochs(clean: Flight, hit: Flight, plan: dict[float, Pair]
                ) -> tuple[int, list[tuple[float, float, float, float]], int]:
    """The hit epochs that were detected (position or velocity not valid), the errors of
    those left valid
    (horizontal and vertical position, m; velocity, m/s; time stamp, us), and how many
    valid fixes of the other epochs differ from the clean flight's."""
    detected = 0
    errors: list[tuple[float, float, float, float]] = []
    for utc in plan:
        got = hit.fixes.get(utc)
        if got is None:
            detected += 1
            continue
        sent = clean.fixes[utc]
        v_sent = clean.velocities.get(sent.t_ns)
        v_got = hit.velocities.get(got.t_ns)
        if v_sent is not None and v_got is None:
            detected += 1  # the epoch's velocity was flagged
            continue
        north, east, down = local_offset_m(_as_epoch(sent), _as_epoch(got))
        dv = 0.0 if v_sent is None or v_got is None else \
            math.dist(v_sent.velocity_ned_m_s, v_got.velocity_ned_m_s)
        errors.append((math.hypot(north, east), abs(down), dv,
                       abs(got.t_ns - sent.t_ns) / 1e3))
    others = sum(1 for utc, fix in hit.fixes.items() if utc not in plan
                 and not _same(clean.fixes.get(utc), fix))
    return detected, errors, others


def flips_row(scenario: str, clean: Flight, hit: Flight, plan: dict[float, Pair]) -> str:
    """Detected, and of the hit epochs left valid those whose position the flips moved."""
    detected, errors, others = _hit_epochs(clean, hit, plan)
    moved = [(h, v) for h, v, _, _ in errors if (h, v) != (0.0, 0.0)]
    worst_h = max((h for h, _ in moved), default=0.0)
    worst_v = max((v for _, v in moved), default=0.0)
    return (f"| {scenario} | {len(plan)} | {detected} | {len(errors) - len(moved)} | "
            f"{len(moved)} | {worst_h:.2f} | {worst_v:.3f} | {others} |")


HOLES = {
    "the same bit 7 flip in a byte of height and of hMSL": heights_pair,
    "velD's lower two bytes, bit 7 or 6": vel_d_pair,
    "nano's lower two bytes, bit 7": nano_pair,
}


def holes_row(name: str, clean: Flight, hit: Flight, plan: dict[float, Pair]) -> str:
    """How many hit epochs were detected, and the largest error of those left valid: the
    position (horizontal, vertical), the velocity and the time stamp."""
    detected, errors, others = _hit_epochs(clean, hit, plan)
    changed = [e for e in errors if any(e)]
    worst = [max((e[k] for e in changed), default=0.0) for k in range(4)]
    return (f"| {name} | {len(plan)} | {detected} | {len(errors) - len(changed)} | "
            f"{len(changed)} | {worst[0]:.2f} | {worst[1]:.3f} | {worst[2]:.3f} | "
            f"{worst[3]:.1f} | {others} |")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--seconds", type=float, default=300.0)
    parser.add_argument("--write", action="store_true")
    args = parser.parse_args(argv)
    registry = load_registry()
    clean_rows: list[str] = []
    flip_rows: list[str] = []
    hole_rows: list[str] = []
    for scenario in SCENARIOS:
        print(f"{scenario}: clean...", file=sys.stderr, flush=True)
        clean = fly(registry, scenario, args.seconds)
        ratios = " | ".join(f"{clean.worst_ratio.get(r, 0.0):.3f}" for r in RULES)
        cross = " | ".join(f"{clean.cross_ratio.get(r, 0.0):.3f}" for r in ("height", "climb"))
        clean_rows.append(f"| {scenario} | {clean.epochs} | "
                          f"{clean.refused.get(UNCONFIRMED, 0)} | {clean.implausible} | "
                          f"{ratios} | {clean.contradicted} | {cross} |")
        faults, plan = hits(clean, args.seconds, random.Random(f"{scenario}/1"))
        print(f"{scenario}: {len(plan)} frames hit...", file=sys.stderr, flush=True)
        flip_rows.append(flips_row(scenario, clean, fly(registry, scenario, args.seconds,
                                                        faults), plan))
        if scenario != SCENARIOS[0]:
            continue
        for name, pair in HOLES.items():
            faults, plan = hits(clean, args.seconds, random.Random(f"{name}/1"), pair)
            print(f"{scenario}: {name}...", file=sys.stderr, flush=True)
            hole_rows.append(holes_row(name, clean, fly(registry, scenario, args.seconds,
                                                        faults), plan))
    given = [f"--seconds={args.seconds:g}"] if args.seconds != 300.0 else []
    text = "\n".join([
        f"Generated by `{generated_by(__file__, given)}`: seed-gps-vario (u-blox NAV-PVT, "
        f"5 Hz, 9600 baud), seed 1, {args.seconds:g} s of each scenario.",
        "",
        "| clean line | fixes | first fixes refused until confirmed | flagged IMPLAUSIBLE "
        "after them | largest residual / bound: horizontal position | vertical position | "
        "geoid separation | time | flagged CONTRADICTED by the barometer | largest residual "
        "/ bound against the barometer: height | climb |",
        "|---|---|---|---|---|---|---|---|---|---|---|",
        *clean_rows,
        "",
        f"| one frame a second from {FIRST_HIT_S:g} s hit by two bit-7 flips the checksum "
        "misses | frames hit | detected (position or velocity flagged, or dropped) | valid, "
        "unchanged | valid, "
        "moved | largest move, horizontal (m) | vertical (m) | other fixes changed |",
        "|---|---|---|---|---|---|---|---|",
        *flip_rows,
        "",
        f"| {SCENARIOS[0]}, one frame a second from {FIRST_HIT_S:g} s hit by | frames hit | "
        "detected (position or velocity flagged, or dropped) | valid, unchanged | valid, "
        "changed | largest error "
        "left valid: horizontal (m) | vertical (m) | velocity (m/s) | time stamp (us) | "
        "other fixes changed |",
        "|---|---|---|---|---|---|---|---|---|---|",
        *hole_rows,
    ])
    print(text)
    if args.write:
        write_block(PAGE, BLOCK, text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
