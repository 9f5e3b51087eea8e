"""Issue 27's "as a user gets it" checks: the bundled profiles and every estimator's defaults,
run the way ``imuhal run --emulate SCENARIO`` runs them.

Every run goes through :func:`imuhal.calibrate.as_user.calibrate_emulated` exactly as
``imuhal run`` does: the accelerometer and magnetometer records a bundled profile lacks are
measured first by imuhal's procedures on the emulated board (``calibration`` scenario, same
seed) and written into the profile; ``--skip-calibration`` measures the board as its file
stores it (gyro offsets at power-up only), what ``imuhal run --skip-calibration`` flies.
The whole profile then runs in one pipeline (its own estimators, plus the added AHRS for the
checks that say so); errors against the scenario's truth at each estimate's time stamp.

Checks (seed 1; errors over t >= 5 s unless stated):

- seed-paraglider-vario, seed-gps-vario and gy91 in ``thermal`` (300 s): the profile's
  ``ahrs`` tilt RMS and max, its ``vario`` climb-rate RMS, and the rest pitch: the mean pitch
  error of the profile's ``ahrs`` over the first 5 s, on the launch before the run-up. The
  GY-91 module is no paraglider instrument (no airspeed in its profile, so no turn
  compensation), but ``thermal`` is the scenario its profile flies.
- ``static`` rolled 180 deg (``roll_deg: 180``, 10 s): every AHRS, added to the seed profile
  with no settings (inputs: imu and mag), worst tilt error from t = 1 s.
- ``rc-flight`` (60 s): the same AHRS added with no settings, worst tilt error from t = 5 s.

``--write`` replaces the block between the ``as-user-table`` markers in docs/estimators.md.
A full run took about 5 minutes before the GY-91's rows; with them, 45 under a load of 20.
"""

from __future__ import annotations

import argparse
import math
import sys
from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from docblock import write_block

from imuhal.calibrate.as_user import calibrate_emulated
from imuhal.emulation import open_emulated
from imuhal.estimation.outputs import AttitudeEstimate, VerticalEstimate
from imuhal.plugins.manager import Registry, load_registry
from imuhal.profile.bundled import default_profile_path
from imuhal.profile.loader import load_profile
from imuhal.profile.model import BoardProfile, EstimatorConfig
from imuhal_filters.common.quat import tilt_error_deg

SEED = 1
SETTLE_S = 5.0
UPSIDE_FROM_S = 1.0
DOC = Path(__file__).resolve().parents[1] / "estimators.md"
PROFILES = ("seed-paraglider-vario", "seed-gps-vario", "gy91")
AHRS = ("madgwick", "mahony", "imufilter", "freescale-9dof", "freescale-6dof", "decoupled",
        "vqf")
TARGETS = {"tilt_rms": 1.0, "tilt_max": 3.0, "climb_rms": 0.05, "rest_pitch": 0.5,
           "upside": 1.0, "rc_max": 10.0}
"""Issue 27's "Done when" bounds (deg; climb m/s)."""


def bundled(registry: Registry, name: str) -> tuple[BoardProfile, str, str]:
    path = default_profile_path().parent / f"{name}.yaml"
    return load_profile(path, registry), path.read_text(encoding="utf-8"), str(path)


def as_run(registry: Registry, name: str, calibrate: bool) -> BoardProfile:
    """The profile ``imuhal run --emulate`` flies (``calibrate``: without
    --skip-calibration)."""
    profile, text, source = bundled(registry, name)
    if not calibrate:
        return profile
    return calibrate_emulated(profile, text, source, registry, seed=SEED).profile


def with_ahrs(profile: BoardProfile, names: Iterable[str]) -> BoardProfile:
    """``profile`` with each AHRS added under its own name, no settings."""
    extra = {n: EstimatorConfig(estimator=n, inputs=["imu", "mag"]) for n in names}
    return profile.model_copy(update={"estimators": {**profile.estimators, **extra}})


@dataclass
class Run:
    attitude: dict[str, list[tuple[float, float, float]]]
    """instance -> (t_s, tilt error deg, pitch error deg)."""
    climb: dict[str, list[tuple[float, float]]]
    """instance -> (t_s, climb-rate error m/s)."""


def _pitch_deg(q: Any) -> float:
    w, x, y, z = (float(v) for v in q)
    return math.degrees(math.asin(max(-1.0, min(1.0, 2.0 * (w * y - z * x)))))


def fly(profile: BoardProfile, registry: Registry, scenario: str, duration_s: float,
        params: dict[str, Any] | None = None) -> Run:
    run = Run({}, {})
    with open_emulated(profile, registry, scenario=scenario, scenario_params=params,
                       seed=SEED) as pipeline:
        world = pipeline.board.scenario  # type: ignore[union-attr]
        for e in pipeline.events(duration_s):
            if isinstance(e, AttitudeEstimate):
                truth = world.truth(e.t_ns / 1e9).q_body_to_ned
                q_true = tuple(float(v) for v in truth)
                run.attitude.setdefault(e.source, []).append(
                    (e.t_ns / 1e9, tilt_error_deg(e.q_body_to_ned, q_true),
                     _pitch_deg(e.q_body_to_ned) - _pitch_deg(q_true)))
            elif isinstance(e, VerticalEstimate):
                run.climb.setdefault(e.source, []).append(
                    (e.t_ns / 1e9, e.climb_m_s - world.truth(e.t_ns / 1e9).climb_m_s))
    return run


def _rms(values: list[float]) -> float:
    return float(np.sqrt(np.mean(np.square(values))))


def _fmt(value: float, target: float, digits: int = 2) -> str:
    text = f"{value:.{digits}f}"
    return text if abs(value) <= target else f"**{text}**"


def measure(registry: Registry, calibrate: bool, thermal_s: float) -> dict[str, Any]:
    out: dict[str, Any] = {"profiles": {}, "upside": {}, "rc": {}}
    for name in PROFILES:
        run = fly(as_run(registry, name, calibrate), registry, "thermal", thermal_s)
        att = run.attitude["ahrs"]
        tilt = [e for t, e, _ in att if t >= SETTLE_S]
        rest = [p for t, _, p in att if t < SETTLE_S]
        climb = [e for t, e in run.climb["vario"] if t >= SETTLE_S]
        out["profiles"][name] = (_rms(tilt), max(tilt), _rms(climb), float(np.mean(rest)))
    names = [n for n in AHRS if n in registry.estimators.names()]
    seed_board = with_ahrs(as_run(registry, PROFILES[0], calibrate), names)
    upside = fly(seed_board, registry, "static", 10.0, {"roll_deg": 180.0})
    rc = fly(seed_board, registry, "rc-flight", 60.0)
    for n in names:
        out["upside"][n] = max(e for t, e, _ in upside.attitude[n] if t >= UPSIDE_FROM_S)
        out["rc"][n] = max(e for t, e, _ in rc.attitude[n] if t >= SETTLE_S)
    return out


def table(results: dict[bool, dict[str, Any]], thermal_s: float) -> str:
    cols = [c for c in (True, False) if c in results]
    head = ["check", "target"] + [
        "`imuhal run` (calibrated first)" if c else "`--skip-calibration`" for c in cols]
    lines = [
        f"Generated by `docs/scripts/as_a_user_gets_it.py` (seed {SEED}; bundled profiles and "
        f"defaults as `imuhal run --emulate` runs them; `thermal` {thermal_s:g} s, errors over "
        f"t >= {SETTLE_S:g} s; rest pitch: mean pitch error over the first {SETTLE_S:g} s; "
        f"upside down: `static` with `roll_deg: 180`, worst tilt from t = {UPSIDE_FROM_S:g} s; "
        "`rc-flight` 60 s; each AHRS added to seed-paraglider-vario with no settings). "
        "Degrees unless stated; a figure over its target is in bold.", "",
        "| " + " | ".join(head) + " |", "| " + " | ".join(["---"] * len(head)) + " |"]
    for name in PROFILES:
        for i, (what, key, unit) in enumerate((
                ("`thermal` tilt RMS", "tilt_rms", 2), ("`thermal` tilt max", "tilt_max", 2),
                ("`thermal` climb RMS (m/s)", "climb_rms", 3),
                ("rest pitch", "rest_pitch", 2))):
            cells = [_fmt(results[c]["profiles"][name][i], TARGETS[key], unit) for c in cols]
            lines.append(f"| {name}: {what} | <= {TARGETS[key]:g} | " + " | ".join(cells) + " |")
    for key, what in (("upside", "upside down, worst tilt from t = 1 s"),
                      ("rc", "`rc-flight` tilt max, defaults")):
        for n in results[cols[0]][key]:
            cells = [_fmt(results[c][key][n], TARGETS["upside" if key == "upside" else "rc_max"])
                     for c in cols]
            bound = TARGETS["upside" if key == "upside" else "rc_max"]
            lines.append(f"| {n}: {what} | <= {bound:g} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--thermal-s", type=float, default=300.0)
    ap.add_argument("--write", action="store_true", help="update docs/estimators.md")
    args = ap.parse_args(argv)
    registry = load_registry()
    results = {c: measure(registry, c, args.thermal_s) for c in (True, False)}
    text = table(results, args.thermal_s)
    print(text)
    if args.write:
        write_block(DOC, "as-user-table", text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
