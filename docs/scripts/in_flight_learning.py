"""Issue 27's in-flight learning target on the uncalibrated seed-gps-vario: does the board
with its calibration removed reach the calibrated board's `thermal` tilt within 2x after five
minutes of flight?

Three runs of the bundled seed-gps-vario, emulated (chips with their datasheet errors, seed
1), flying `thermal` for ``--duration`` seconds with the profile's own estimators:

- **calibrated**: what ``imuhal run`` flies (accelerometer and magnetometer measured first,
  imuhal.calibrate.as_user);
- **uncalibrated**: the profile as stored (``--skip-calibration``: gyro offsets at power-up);
- **uncalibrated, mag_in_flight**: the same, the magnetometer learning its hard iron in
  flight (imuhal.calibration.hard_iron).

Printed: the profile's ``ahrs`` tilt and heading RMS error over the last 60 s of the flight,
and for the learning run when the hard iron converged and how far it lies from the
figure-of-8 ellipsoid fit of the same board. About 3 minutes.
"""

from __future__ import annotations

import argparse
import math
import sys
from typing import Any

import numpy as np

from imuhal.calibrate.as_user import calibrate_emulated
from imuhal.calibrate.emulated import measure_board_calibration
from imuhal.calibration.model import DeviceCalibration, MagInFlightSettings
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


def _yaw_deg(q: Any) -> float:
    w, x, y, z = (float(v) for v in q)
    return math.degrees(math.atan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z)))


def fly(profile: BoardProfile, registry: Registry, duration_s: float) -> dict[str, Any]:
    tilt, heading, converged_s = [], [], None
    with open_emulated(profile, registry, scenario="thermal", seed=SEED) as pipeline:
        world = pipeline.board.scenario  # type: ignore[union-attr]
        learner = pipeline.devices["mag"].mag_learner
        for e in pipeline.events(duration_s):
            if learner is not None and converged_s is None and learner.converged \
                    and isinstance(e, Sample):
                converged_s = e.t_ns / 1e9
            if isinstance(e, AttitudeEstimate) and e.source == "ahrs" \
                    and e.t_ns >= (duration_s - LAST_S) * 1e9:
                q = tuple(float(v) for v in world.truth(e.t_ns / 1e9).q_body_to_ned)
                tilt.append(tilt_error_deg(e.q_body_to_ned, q))
                heading.append((_yaw_deg(e.q_body_to_ned) - _yaw_deg(q) + 180) % 360 - 180)
        learned = learner.hard_iron_ut() if learner is not None else None
    return {"tilt": float(np.sqrt(np.mean(np.square(tilt)))),
            "heading": float(np.sqrt(np.mean(np.square(heading)))),
            "converged_s": converged_s, "learned": learned}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--duration", type=float, default=300.0)
    args = ap.parse_args(argv)
    registry = load_registry()
    stored = load_profile(PATH, registry)
    text = PATH.read_text(encoding="utf-8")
    calibrated = calibrate_emulated(stored, text, str(PATH), registry, seed=SEED).profile
    devices = dict(stored.devices)
    devices["mag"] = devices["mag"].model_copy(
        update={"calibration": DeviceCalibration(mag_in_flight=MagInFlightSettings())})
    learning = stored.model_copy(update={"devices": devices})
    reference = measure_board_calibration(stored, registry, seed=SEED)["mag"].mag
    assert reference is not None
    runs = {"calibrated": calibrated, "uncalibrated": stored,
            "uncalibrated, mag_in_flight": learning}
    print(f"seed-gps-vario, `thermal` {args.duration:g} s, seed {SEED}; profile's ahrs; "
          f"RMS over the last {LAST_S:g} s (deg)\n")
    print("| board | tilt RMS | heading RMS | hard iron converged at (s) | "
          "learned - ellipsoid fit (uT) |")
    print("| --- | ---: | ---: | ---: | --- |")
    for name, profile in runs.items():
        r = fly(profile, registry, args.duration)
        conv = "—" if r["converged_s"] is None else f"{r['converged_s']:.0f}"
        diff = "—" if r["learned"] is None else "(" + ", ".join(
            f"{a - b:+.2f}" for a, b in zip(r["learned"], reference.hard_iron_ut,
                                             strict=True)) + ")"
        print(f"| {name} | {r['tilt']:.2f} | {r['heading']:.2f} | {conv} | {diff} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
