"""Attitudes withheld after an IMU outage (docs/reliability.md, ``outage-withheld`` block):
how long the AHRS withholds its attitude after a span of unmeasured rotation, and how far off
the truth the attitudes it hands out after it are.

Two tables (seed 1):

* **a 2 s `absent` IMU in a turn** (20-22 s, `thermal`'s first circles; the plan of
  tests/integration/test_attitude_after_an_outage_in_a_turn.py), 45 s: the GY-91 as bundled
  (no speed source: its AHRS compensates no turn), the GY-91 with a trim speed stated on its
  AHRS (``nominal_airspeed_m_s: 10``, as the seed boards state), and the seed paraglider
  vario as bundled;
* **the soak's `frozen` IMU window** (seed-paraglider-vario, the 300 s plan of
  tests/benchmarks/soak.py: every fault kind once, 1 % bus errors; the IMU frozen
  127.5-132.5 s, in a glide), flown to 175 s: the worst tilt handed out in the 7.5 s before
  the window, and the same columns after it.

Columns: the first attitude handed out after the outage's end (s after it), the attitudes
withheld after it, those handed out to the flight's end, and the worst tilt of those against
the truth (deg).

Usage: ``docs/scripts/outage_in_a_turn.py [--write]`` (prints the block; ``--write``
replaces it in docs/reliability.md).
"""

from __future__ import annotations

import argparse
import sys
from dataclasses import dataclass

from docblock import ROOT, generated_by, write_block

from imuhal.emulation import open_emulated
from imuhal.emulation.faults import ChipAbsent, FaultSpec
from imuhal.estimation.outputs import AttitudeEstimate, RejectedEstimate
from imuhal.plugins.manager import Registry, load_registry
from imuhal.profile.bundled import bundled_profiles
from imuhal.profile.loader import parse_profile, read_profile_text
from imuhal.profile.model import BoardProfile
from imuhal_filters.common.quat import tilt_error_deg

sys.path.insert(0, str(ROOT))
from tests.benchmarks import fault_truth  # the soak's plan
from tests.benchmarks.soak import fault_plan, scenario_params

PAGE = ROOT / "docs" / "reliability.md"
BLOCK = "outage-withheld"
SEED = 1
OUTAGE_S = (20.0, 22.0)
TURN_END_S = 45.0
SOAK_S = 300.0
FROZEN_S = (127.5, 132.5)
SOAK_END_S = 175.0
BEFORE_S = 7.5
TRIM = "    settings:\n      nominal_airspeed_m_s: 10\n  vario:\n"


@dataclass
class After:
    """What the AHRS gave after an outage that ended at ``end_s``."""

    end_s: float
    first_s: float | None = None
    withheld: int = 0
    handed_out: int = 0
    worst_deg: float = 0.0
    worst_before_deg: float = 0.0

    def row(self, name: str) -> str:
        first = "none" if self.first_s is None else f"{self.first_s - self.end_s:.2f}"
        return (f"| {name} | {first} | {self.withheld} | {self.handed_out} | "
                f"{self.worst_deg:.2f} |")


def profile(registry: Registry, board: str, trim: bool = False) -> BoardProfile:
    text = read_profile_text(bundled_profiles()[f"{board}.yaml"])
    if trim:
        assert "\n  vario:\n" in text and "nominal_airspeed_m_s" not in text
        text = text.replace("  vario:\n", TRIM, 1)
    return parse_profile(text, board, registry)


def fly(prof: BoardProfile, registry: Registry, faults: list[FaultSpec], end_s: float,
        outage: tuple[float, float], **params: object) -> After:
    out = After(end_s=outage[1])
    with open_emulated(prof, registry, seed=SEED, faults=faults, **params) as p:  # type: ignore[arg-type]
        truth = p.board.scenario.truth  # type: ignore[union-attr]  # an emulated board
        for e in p.events(end_s):
            if getattr(e, "source", None) != "ahrs":
                continue
            t_s = e.t_ns / 1e9
            if isinstance(e, AttitudeEstimate):
                err = tilt_error_deg(e.q_body_to_ned, tuple(truth(t_s).q_body_to_ned))
                if outage[0] - BEFORE_S <= t_s < outage[0]:
                    out.worst_before_deg = max(out.worst_before_deg, err)
                if t_s >= outage[1]:
                    out.handed_out += 1
                    out.worst_deg = max(out.worst_deg, err)
                    if out.first_s is None:
                        out.first_s = t_s
            elif isinstance(e, RejectedEstimate) and t_s >= outage[1]:
                out.withheld += 1
    return out


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--write", action="store_true")
    args = parser.parse_args(argv)
    registry = load_registry()
    absent: list[FaultSpec] = [ChipAbsent(device="imu", start_s=OUTAGE_S[0],
                                          end_s=OUTAGE_S[1])]
    turn_rows = []
    for name, board, trim in (("gy91 as bundled", "gy91", False),
                              ("gy91, trim speed 10 m/s stated", "gy91", True),
                              ("seed-paraglider-vario as bundled", "seed-paraglider-vario",
                               False)):
        print(f"turn: {name}...", file=sys.stderr, flush=True)
        turn_rows.append(fly(profile(registry, board, trim), registry, absent, TURN_END_S,
                             OUTAGE_S).row(name))
    print("soak: frozen window...", file=sys.stderr, flush=True)
    glider = profile(registry, "seed-paraglider-vario")
    plan = fault_plan(fault_truth.devices_of(glider, registry), SOAK_S)
    soak = fly(glider, registry, plan, SOAK_END_S, FROZEN_S,
               scenario_params=scenario_params(glider, SOAK_S))
    text = "\n".join([
        f"Generated by `{generated_by(__file__, [])}`: seed {SEED}.",
        "",
        f"| a 2 s `absent` IMU at {OUTAGE_S[0]:g}-{OUTAGE_S[1]:g} s in `thermal`'s first "
        f"circles, {TURN_END_S:g} s | first attitude after it (s) | withheld after it | "
        "handed out after it | worst tilt handed out after it (deg) |",
        "|---|---|---|---|---|",
        *turn_rows,
        "",
        f"| seed-paraglider-vario, the soak's {SOAK_S:g} s plan, the IMU `frozen` "
        f"{FROZEN_S[0]:g}-{FROZEN_S[1]:g} s, to {SOAK_END_S:g} s | worst tilt handed out "
        f"in the {BEFORE_S:g} s before it (deg) | first attitude after it (s) | withheld "
        "after it | handed out after it | worst tilt handed out after it (deg) |",
        "|---|---|---|---|---|---|",
        soak.row("as bundled").replace("| as bundled |",
                                       f"| as bundled | {soak.worst_before_deg:.2f} |"),
    ])
    print(text)
    if args.write:
        write_block(PAGE, BLOCK, text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
