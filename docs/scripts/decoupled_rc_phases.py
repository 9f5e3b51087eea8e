"""The decoupled estimator against madgwick in `rc-flight`, phase by phase
(docs/estimators.md, decoupled section).

Usage::

    .venv/bin/python docs/scripts/decoupled_rc_phases.py [--window S] [NAME:JSON ...]

Flies ``rc-flight`` once (the flight benchmark's calibrated seed board, seed 1, 60 s) and
prints, per window of ``--window`` seconds, the mean tilt error (deg) of each estimator and
settings given (default: madgwick, decoupled, decoupled without its turbulence correction,
and decoupled with a 1e-4 g gate and no turbulence correction, which is the gyro alone once
airborne), with the mean | |a| - 1 g | of the accelerometer samples and the mean weight the
decoupled default soft gate gives them (the share of each step its inclination filter
advances by).
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

import flight_benchmark as fb

from imuhal.core.samples import AccelSample
from imuhal.plugins.manager import load_registry
from imuhal_filters.common.gate import gravity_positive_g, soft_gate_weight

DEFAULT_RUNS = ('madgwick:{}', 'decoupled:{}', 'decoupled:{"turbulence_rate_deg_s": null}',
                'decoupled:{"accel_soft_gate_g": 0.0001, "turbulence_rate_deg_s": null}')
DEFAULT_GATE_G = 0.02


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--window", type=float, default=3.0, metavar="S")
    parser.add_argument("runs", nargs="*", default=list(DEFAULT_RUNS))
    args = parser.parse_args(argv)
    reg = load_registry()
    profile = fb.calibrated_seed_profile(reg)
    rc = fb.fly(profile, reg, "rc-flight", 60.0)
    a_t = np.array([s.t_ns / 1e9 for s in rc.samples if isinstance(s, AccelSample)])
    a_g = [gravity_positive_g(s.accel_m_s2) for s in rc.samples if isinstance(s, AccelSample)]
    dev = np.array([abs(math.sqrt(sum(c * c for c in a)) - 1.0) for a in a_g])
    weight = np.array([soft_gate_weight(a, DEFAULT_GATE_G) for a in a_g])
    series = []
    for run in args.runs:
        name, _, raw = run.partition(":")
        est = reg.estimators.get(name)({"sample_period_s": 0.004, **json.loads(raw or "{}")})
        out = fb.run_ahrs(est, rc.samples)
        f = fb.tilt_figures(rc, out)
        print(f"{run}: tilt RMS {f.rms_deg:.2f} / max {f.max_deg:.1f} deg")
        t = np.array([e.t_ns / 1e9 for e in out])
        err = np.array([fb._tilt_deg(e.q_body_to_ned, rc.truth(e.t_ns).q_body_to_ned)
                        for e in out])
        series.append((t, err))
    print("| window (s) | " + " | ".join(args.runs) + " | mean abs(|a| - 1 g) | mean gate weight |")
    w = args.window
    for k in range(int(60.0 / w)):
        lo, hi = k * w, (k + 1) * w
        cells = [f"{err[(t >= lo) & (t < hi)].mean():.2f}" for t, err in series]
        m = (a_t >= lo) & (a_t < hi)
        print(f"| {lo:g}-{hi:g} | " + " | ".join(cells)
              + f" | {dev[m].mean():.3f} | {weight[m].mean():.3f} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
