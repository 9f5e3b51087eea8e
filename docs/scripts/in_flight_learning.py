"""Issue 27's in-flight learning target on the uncalibrated seed-gps-vario: does the board
with its calibration removed reach the calibrated board's `thermal` tilt within 2x after five
minutes of flight?

Four runs of the bundled seed-gps-vario, emulated (chips with their datasheet errors, seed
1), flying `thermal` for ``--duration`` seconds with the profile's own estimators:

- **calibrated**: what ``imuhal run`` flies (accelerometer and magnetometer measured first,
  imuhal.calibrate.as_user);
- **uncalibrated, defaults**: the profile as stored, flown as ``imuhal run
  --skip-calibration`` flies it (gyro offsets at power-up); with no accelerometer or
  magnetometer record the board learns both in flight by default (the magnetometer's hard
  iron, imuhal.calibration.hard_iron; the accelerometer's offset from the GNSS velocity,
  imuhal.calibration.accel_in_flight; imuhal.pipeline.learning ``learned_by_default``);
- **uncalibrated, accel_in_flight: off**: the same, the accelerometer's learning turned off
  in the profile (the hard iron still learned);
- **uncalibrated, both off**: ``mag_in_flight: off`` and ``accel_in_flight: off``: the raw
  board.

Printed: the profile's ``ahrs`` tilt and heading RMS error over the last 60 s of the flight,
its ratio to the calibrated board's tilt (issue 27's target: at most 2), and for the
learning runs when each learner converged and how far its value lies from the procedure's
record of the same board (the figure-of-8 ellipsoid fit; the six-position fit, sensor
frame). About 6 minutes; ``--write`` puts the table into docs/calibration.md.
"""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path
from typing import Any

import numpy as np
from docblock import write_block

from imuhal.calibrate.as_user import calibrate_emulated
from imuhal.calibrate.emulated import measure_board_calibration
from imuhal.calibration.accel_in_flight import MG
from imuhal.calibration.model import DeviceCalibration
from imuhal.core.samples import Sample
from imuhal.emulation import open_emulated
from imuhal.estimation.outputs import AttitudeEstimate
from imuhal.plugins.manager import Registry, load_registry
from imuhal.profile.bundled import default_profile_path
from imuhal.profile.loader import load_profile
from imuhal.profile.model import BoardProfile
from imuhal_filters.common.quat import tilt_error_deg

SEED = 1
LAST_S = 60.0
PATH = default_profile_path().parent / "seed-gps-vario.yaml"
DOC = Path(__file__).resolve().parents[1] / "calibration.md"


def _yaw_deg(q: Any) -> float:
    w, x, y, z = (float(v) for v in q)
    return math.degrees(math.atan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z)))


def fly(profile: BoardProfile, registry: Registry, duration_s: float) -> dict[str, Any]:
    tilt, heading, converged_s, accel_s = [], [], None, None
    with open_emulated(profile, registry, scenario="thermal", seed=SEED) as pipeline:
        world = pipeline.board.scenario  # type: ignore[union-attr]
        learner = pipeline.devices["mag"].mag_learner
        teacher = pipeline.devices["imu"].accel_teacher
        for e in pipeline.events(duration_s):
            if learner is not None and converged_s is None and learner.converged \
                    and isinstance(e, Sample):
                converged_s = e.t_ns / 1e9
            if teacher is not None and accel_s is None and teacher.learner.converged \
                    and isinstance(e, Sample):
                accel_s = e.t_ns / 1e9
            if isinstance(e, AttitudeEstimate) and e.source == "ahrs" \
                    and e.t_ns >= (duration_s - LAST_S) * 1e9:
                q = tuple(float(v) for v in world.truth(e.t_ns / 1e9).q_body_to_ned)
                tilt.append(tilt_error_deg(e.q_body_to_ned, q))
                heading.append((_yaw_deg(e.q_body_to_ned) - _yaw_deg(q) + 180) % 360 - 180)
        learned = learner.hard_iron_ut() if learner is not None else None
        cal = pipeline.devices["imu"].calibration
        offset = cal.accel.offset_m_s2 if teacher is not None and cal is not None \
            and cal.accel is not None else None
    return {"tilt": float(np.sqrt(np.mean(np.square(tilt)))),
            "heading": float(np.sqrt(np.mean(np.square(heading)))),
            "converged_s": converged_s, "learned": learned,
            "accel_s": accel_s, "offset": offset}


def _turned_off(stored: BoardProfile, accel: bool, mag: bool) -> BoardProfile:
    """``stored`` with its accelerometer's (``accel``) and magnetometer's (``mag``) learning
    in flight turned off in the profile (``<channel>_in_flight: off``)."""
    devices = dict(stored.devices)
    for device, key, off in (("imu", "accel_in_flight", accel), ("mag", "mag_in_flight", mag)):
        if off:
            cal = devices[device].calibration or DeviceCalibration()
            devices[device] = devices[device].model_copy(update={
                "calibration": DeviceCalibration.model_validate(
                    {**cal.model_dump(exclude_none=True), key: "off"})})
    return stored.model_copy(update={"devices": devices})


def _diff(values: Any, reference: Any, unit: float = 1.0) -> str:
    if values is None:
        return "—"
    return "(" + ", ".join(f"{(a - b) / unit:+.2f}" for a, b in zip(values, reference,
                                                                    strict=True)) + ")"


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--duration", type=float, default=300.0)
    ap.add_argument("--write", action="store_true",
                    help=f"update the table in {DOC.relative_to(DOC.parents[1])}")
    args = ap.parse_args(argv)
    registry = load_registry()
    stored = load_profile(PATH, registry)
    text = PATH.read_text(encoding="utf-8")
    calibrated = calibrate_emulated(stored, text, str(PATH), registry, seed=SEED).profile
    measured = measure_board_calibration(stored, registry, seed=SEED)
    reference, six = measured["mag"].mag, measured["imu"].accel
    assert reference is not None and six is not None
    runs = {"calibrated": calibrated,
            "uncalibrated, defaults (learns both in flight)": stored,
            "uncalibrated, `accel_in_flight: off`": _turned_off(stored, accel=True, mag=False),
            "uncalibrated, both `off` (raw board)": _turned_off(stored, accel=True, mag=True)}
    lines = ["Generated by `docs/scripts/in_flight_learning.py` (about 6 minutes):", "",
             f"seed-gps-vario, `thermal` {args.duration:g} s, seed {SEED}; profile's ahrs; "
             "learners with their default settings; "
             f"RMS over the last {LAST_S:g} s (deg); tilt / calibrated: the ratio to the "
             "calibrated board's tilt RMS", "",
             "| board | tilt RMS | tilt / calibrated | heading RMS | hard iron converged at (s) "
             "| learned - ellipsoid fit (uT) | accel offset converged at (s) "
             "| learned - six-position fit (mg, sensor frame) |",
             "| --- | ---: | ---: | ---: | ---: | --- | ---: | --- |"]
    base = None
    for name, profile in runs.items():
        r = fly(profile, registry, args.duration)
        base = r["tilt"] if base is None else base
        conv = "—" if r["converged_s"] is None else f"{r['converged_s']:.0f}"
        accel = "—" if r["accel_s"] is None else f"{r['accel_s']:.0f}"
        lines.append(f"| {name} | {r['tilt']:.2f} | {r['tilt'] / base:.2f} | "
                     f"{r['heading']:.2f} | {conv} | "
                     f"{_diff(r['learned'], reference.hard_iron_ut)} | {accel} | "
                     f"{_diff(r['offset'], six.offset_m_s2, MG)} |")
    table = "\n".join(lines)
    print(table)
    if args.write:
        write_block(DOC, "learning-table", table)
    return 0


if __name__ == "__main__":
    sys.exit(main())
