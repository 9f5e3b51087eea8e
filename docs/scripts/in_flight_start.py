"""A board switched on in flight (a brown-out reboot, a battery swap in the air): what each
bundled board hands out as valid after it (issue 26).

Each of the three seed boards and the GY-91, as its profile flies its own scenario (seed 1,
the profile's stored calibration, ``imuhal run --emulate`` without calibrating first), is
switched on ``START_S`` seconds into the flight (``open_emulated(start_s=...)``) and runs
``--duration`` seconds from there; the row switched on at 0 is the ordinary ground start,
for comparison. Per run: the time from switch-on to the first attitude and the first climb
rate, how many vertical estimates were withheld (UNSETTLED) and handed out, how many valid
ones are more than ``CLIMB_BOUND_M_S`` off the simulation's true climb rate in the first
``TRANSIENT_S`` after their estimator first spoke (the start-up's transient) and how many
more than ``CLIMB_MARGIN_M_S`` off anywhere, the worst climb-rate error of a valid estimate
in the transient, and of the profile's ``ahrs``: how many attitudes it withheld (its start
check, ``start_check_s``, and any other reason), how many valid ones are more than
``TILT_BOUND_DEG`` off the true tilt, and the worst tilt error of a valid attitude.
``--write`` replaces the block between the ``in-flight-start`` markers in docs/reliability.md.
About 5 minutes under load (``--boards``, ``--starts``: a subset, not written).
``--gyro-attempts N`` gives every device's start-up gyro measurement (``gyro_at_startup``) N
attempts instead of the profile's (1 by default): how the boards fare when the start-up
waits for a still board (not written to the docs' block)."""

from __future__ import annotations

import argparse
import math
import sys
from dataclasses import dataclass
from pathlib import Path

from docblock import write_block

from imuhal.emulation import open_emulated
from imuhal.estimation.outputs import AttitudeEstimate, RejectedEstimate, VerticalEstimate
from imuhal.plugins.manager import Registry, load_registry
from imuhal.profile.bundled import bundled_profiles
from imuhal.profile.loader import load_profile
from imuhal.profile.model import BoardProfile
from imuhal_filters.common.quat import tilt_error_deg

SEED = 1
BOARDS = ("seed-gps-vario", "seed-paraglider-vario", "seed-rc-vario", "gy91")
START_S = (0.0, 20.0, 38.0)
"""Switch-on times (s into the scenario): 0 on the ground; 20 and 38 in `thermal` circling in
the thermal (launch at 5 s), in `rc-flight` in the circuit after the climb-out."""
CLIMB_BOUND_M_S = 1.0
"""In the start-up's transient a valid climb rate further than this from the truth counts as
wrong (m/s): the bound tests/integration/test_in_flight_start.py states (4 settled climb
sigmas of vario-kf3, 0.25 m/s; 2.5 of baro-vario, 0.4 m/s)."""
TRANSIENT_S = 5.0
"""The start-up's transient: the first seconds after a vertical estimator first speaks. Later,
the filters' ordinary tracking error is the flight's (a ground-started seed-rc-vario hands
out 173 climb rates more than 1 m/s off in 45 s of `rc-flight`'s manoeuvres; baro-only lags
a thermal's edge by more), judged with the fault matrix's margin."""
CLIMB_MARGIN_M_S = 3.0
"""Anywhere in the run, a valid climb rate further than this is wrong (m/s): the fault
matrix's margin (tests/benchmarks/fault_matrix.py, tests/integration/test_vario_unsettled.py)."""
TILT_BOUND_DEG = 10.0
"""A valid attitude further than this from the true tilt counts as wrong (deg): the fault
matrix's margin (tests/benchmarks/fault_truth.py) and the flight benchmark's rc-flight
target; the ground starts' worst is 3-6 deg."""
DOC = Path(__file__).resolve().parents[1] / "reliability.md"


@dataclass(frozen=True)
class Start:
    board: str
    start_s: float
    first_attitude_s: float
    first_climb_s: float
    withheld: int
    valid: int
    wrong_transient: int
    wrong_anywhere: int
    worst_transient_m_s: float
    attitudes_withheld: int
    tilt_wrong: int
    worst_tilt_deg: float


def with_gyro_attempts(profile: BoardProfile, attempts: int) -> BoardProfile:
    """``profile`` with every ``gyro_at_startup`` measurement given ``attempts`` attempts."""
    devices = dict(profile.devices)
    for name, dev in devices.items():
        cal = dev.calibration
        if cal is not None and cal.gyro_at_startup is not None:
            startup = cal.gyro_at_startup.model_copy(update={"max_attempts": attempts})
            cal = cal.model_copy(update={"gyro_at_startup": startup})
            devices[name] = dev.model_copy(update={"calibration": cal})
    return profile.model_copy(update={"devices": devices})


def fly(registry: Registry, board: str, start_s: float, duration_s: float,
        gyro_attempts: int | None = None) -> Start:
    """``board`` switched on at ``start_s`` of its scenario, ``duration_s`` seconds."""
    profile = load_profile(bundled_profiles()[f"{board}.yaml"], registry)
    if gyro_attempts is not None:
        profile = with_gyro_attempts(profile, gyro_attempts)
    first_att = first_climb = math.nan
    withheld = valid = wrong_transient = wrong_anywhere = att_withheld = tilt_wrong = 0
    worst_climb = worst_tilt = 0.0
    spoke: dict[str, float] = {}
    with open_emulated(profile, registry, seed=SEED, start_s=start_s) as pipeline:
        truth = pipeline.board.scenario.truth  # type: ignore[attr-defined]  # emulated board
        for e in pipeline.events(duration_s):
            if isinstance(e, VerticalEstimate):
                t = e.t_ns / 1e9
                if math.isnan(first_climb):
                    first_climb = t - start_s
                err = abs(e.climb_m_s - truth(t).climb_m_s)
                valid += 1
                wrong_anywhere += err > CLIMB_MARGIN_M_S
                if t - spoke.setdefault(e.source, t) <= TRANSIENT_S:
                    wrong_transient += err > CLIMB_BOUND_M_S
                    worst_climb = max(worst_climb, err)
            elif isinstance(e, RejectedEstimate) and e.kind == "vertical":
                withheld += 1
            elif isinstance(e, RejectedEstimate) and e.source == "ahrs":
                att_withheld += 1
            elif isinstance(e, AttitudeEstimate) and e.source == "ahrs":
                t = e.t_ns / 1e9
                if math.isnan(first_att):
                    first_att = t - start_s
                tilt = tilt_error_deg(e.q_body_to_ned, tuple(truth(t).q_body_to_ned))
                tilt_wrong += tilt > TILT_BOUND_DEG
                worst_tilt = max(worst_tilt, tilt)
    return Start(board, start_s, first_att, first_climb, withheld, valid, wrong_transient,
                 wrong_anywhere, worst_climb, att_withheld, tilt_wrong, worst_tilt)


def table(rows: list[Start], duration_s: float, gyro_attempts: int | None = None) -> str:
    head = ["board", "switched on at (s)", "first attitude after (s)",
            "first climb rate after (s)", "climb rates withheld", "climb rates valid",
            f"first {TRANSIENT_S:g} s: valid > {CLIMB_BOUND_M_S:g} m/s off",
            f"first {TRANSIENT_S:g} s: worst valid climb error (m/s)",
            f"anywhere: valid > {CLIMB_MARGIN_M_S:g} m/s off", "attitudes withheld",
            f"valid tilt > {TILT_BOUND_DEG:g}° off", "worst valid tilt error (°)"]
    extra = "" if gyro_attempts is None else f" --gyro-attempts {gyro_attempts}"
    lines = [f"Generated by `docs/scripts/in_flight_start.py --duration {duration_s:g}{extra}` "
             f"(seed {SEED}; each bundled board as its profile flies its own scenario, "
             f"switched on at the time shown and run {duration_s:g} s from there; every "
             "vertical estimator of the profile, the first seconds counted from when each "
             "first spoke; tilt: the profile's `ahrs`):", "",
             "| " + " | ".join(head) + " |", "| --- |" + " ---: |" * (len(head) - 1)]
    def after(s: float) -> str:
        return "never" if math.isnan(s) else f"{s:.2f}"

    for r in rows:
        climb = "—" if r.valid == 0 else f"{r.worst_transient_m_s:.2f}"
        tilt = "—" if math.isnan(r.first_attitude_s) else f"{r.worst_tilt_deg:.1f}"
        lines.append(
            f"| {r.board} | {r.start_s:g} | {after(r.first_attitude_s)} "
            f"| {after(r.first_climb_s)} | {r.withheld} | {r.valid} | {r.wrong_transient} "
            f"| {climb} | {r.wrong_anywhere} | {r.attitudes_withheld} | {r.tilt_wrong} "
            f"| {tilt} |")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--duration", type=float, default=20.0)
    ap.add_argument("--gyro-attempts", type=int, default=None,
                    help="attempts of the start-up gyro measurement (default: the profile's)")
    ap.add_argument("--boards", nargs="+", default=list(BOARDS), choices=BOARDS,
                    help="only these boards (not written to the docs' block)")
    ap.add_argument("--starts", nargs="+", type=float, default=list(START_S),
                    help="only these switch-on times, s (not written to the docs' block)")
    ap.add_argument("--write", action="store_true",
                    help=f"update the block in {DOC.relative_to(DOC.parents[1])}")
    args = ap.parse_args(argv)
    registry = load_registry()
    rows = []
    for board in args.boards:
        for start in args.starts:
            rows.append(fly(registry, board, start, args.duration, args.gyro_attempts))
            print(f"{board} at {start:g} s done", file=sys.stderr)
    text = table(rows, args.duration, args.gyro_attempts)
    print(text)
    whole = args.boards == list(BOARDS) and args.starts == list(START_S)
    if args.write and args.gyro_attempts is None and whole:
        write_block(DOC, "in-flight-start", text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
