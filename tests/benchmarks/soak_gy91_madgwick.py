"""The soak of tests/benchmarks/soak.py on the bundled GY-91 with the Madgwick (beta 0.1) its
profile ran before issue 27 item 3 made it `decoupled`: the same plan, the same checker, to
set the two AHRS side by side (plain script; not collected by pytest).

Run:  nice -n 10 .venv/bin/python -m tests.benchmarks.soak_gy91_madgwick [--duration 120]
      [--json FILE]

Start-up trials are not run (they do not depend on the AHRS). ``soak.py --board gy91
--startups 0`` gives the profile's own `decoupled` on the same plan.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence

from tests.benchmarks.soak import Checkpoint, Report, markdown, soak

from imuhal.plugins.manager import load_registry
from imuhal.profile.bundled import bundled_profiles
from imuhal.profile.loader import load_profile


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--duration", type=float, default=120.0, help="simulated seconds")
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--json", metavar="FILE", help="also write the report as JSON")
    args = parser.parse_args(argv)
    registry = load_registry()
    profile = load_profile(bundled_profiles()["gy91.yaml"], registry)
    ahrs = profile.estimators["ahrs"].model_copy(
        update={"estimator": "madgwick", "settings": {"beta": 0.1}})
    profile = profile.model_copy(update={"estimators": {**profile.estimators, "ahrs": ahrs}})
    report = Report(duration_s=args.duration, seed=args.seed, board="gy91")
    report.startups = (0, 0)  # not run: they do not depend on the AHRS
    checkpoint = Checkpoint(args.json)
    checkpoint.reports.append(report)
    soak("gy91", profile, registry, report, checkpoint, progress=False)
    checkpoint.write()
    print(markdown(report))
    print(f"\nattitudes handed out {dict(report.attitudes)}, more than 10 deg off "
          f"{dict(report.tilt_over)}, worst {report.worst_tilt_deg}, withheld "
          f"{dict(report.rejected_estimates)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
