"""The angular-rate recovery figures in docs/estimators.md ("Saturation is recovered").

Usage::

    .venv/bin/python docs/scripts/angular_rate_recovery.py [ESTIMATOR ...]

The seed board (profiles/seed-paraglider-vario.yaml, emulated with its chips' error models,
seed 3) with its gyro set to +-250 deg/s makes one full roll in 0.8 s after 2 s still (the
``tumble`` scenario shortened: up to about 10 rad/s, clipped for about 0.6 s). For each
estimator (default: madgwick, mahony) and each ``gyro_saturation`` (recover, drop) it prints
the worst tilt error (deg) 0.5-2 s after the roll and the recovery's counters. The same
flight as tests/filters/test_angular_rate_recovery.py.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

from imuhal.emulation.open import open_emulated
from imuhal.estimation.outputs import AttitudeEstimate
from imuhal.plugins.manager import load_registry
from imuhal.profile.loader import parse_profile
from imuhal_filters.common.quat import tilt_error_deg

PROFILE = Path(__file__).resolve().parents[2] / "profiles" / "seed-paraglider-vario.yaml"
QUICK_ROLL = {"axes": [[1.0, 0.0, 0.0]], "rotation_s": 0.8, "ramp_s": 0.2, "hold_s": 2.0,
              "free_tumble_s": 0.0}
ROLL_ENDS_S = 2.8
WINDOW_S = (0.5, 2.0)


def worst_after_roll(estimator: str, saturation: str) -> tuple[float, dict[str, object]]:
    registry = load_registry()
    text = PROFILE.read_text().replace("gyro_range_dps: 500", "gyro_range_dps: 250")
    text = text.replace("estimator: madgwick ", f"estimator: {estimator} ")
    text = text.replace("nominal_airspeed_m_s: 10\n",
                        f"nominal_airspeed_m_s: 10\n      gyro_saturation: {saturation}\n")
    profile = parse_profile(text, "quick-roll", registry)
    truth = registry.scenarios.get("tumble")(QUICK_ROLL, seed=3)
    worst = 0.0
    with open_emulated(profile, registry, scenario="tumble", scenario_params=QUICK_ROLL,
                       seed=3) as pipeline:
        for event in pipeline.events(ROLL_ENDS_S + WINDOW_S[1]):
            if isinstance(event, AttitudeEstimate) and event.source == "ahrs":
                t = event.t_ns / 1e9
                if ROLL_ENDS_S + WINDOW_S[0] <= t <= ROLL_ENDS_S + WINDOW_S[1]:
                    err = tilt_error_deg(event.q_body_to_ned,
                                         tuple(np.asarray(truth.truth(t).q_body_to_ned)))
                    worst = max(worst, err)
        ahrs = next(r.estimator for r in pipeline.estimators if r.name == "ahrs")
        return worst, ahrs.diagnostics()["angular_rate_recovery"]


def main(names: list[str]) -> None:
    print(f"worst tilt error {WINDOW_S[0]:g}-{WINDOW_S[1]:g} s after a roll beyond "
          "+-250 deg/s (deg)")
    for name in names or ["madgwick", "mahony"]:
        for saturation in ("recover", "drop"):
            worst, recovery = worst_after_roll(name, saturation)
            print(f"  {name:10s} {saturation:8s} {worst:6.2f}   {recovery}")


if __name__ == "__main__":
    main(sys.argv[1:])
