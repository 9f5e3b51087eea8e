"""Regenerate the inputs of the Freescale high-g reference test from imuhal's own scenario.

    .venv/bin/python docs/scripts/fsl_highg/make_inputs.py OUT_DIR

writes ``fsl_highg_counts.csv`` (the 560 fast samples the reference and the port are fed)
and ``fsl_highg_truth.csv`` (the true attitude at the Kalman rows) into OUT_DIR, byte for
byte as committed in tests/data/filters (``--check`` compares and exits non-zero on any
difference). The reference outputs for these inputs come from ``harness.c`` in this folder
(README.md here).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from imuhal.plugins.manager import load_registry

G = 9.80665
RATE_HZ = 200
FIRST, LAST = 3120, 3679
"""Fast rows of the run in the slice: 0.4 s of cruise, then the first 2.4 s of the loop."""
OVERSAMPLE = 8
PARAMS = {"environment": {"field_intensity_ut": 50.0, "inclination_deg": 60.0,
                          "declination_deg": 0.0}}
HEADER_COMMON = (
    "imuhal rc-flight scenario (src/imuhal/sim/rc_flight.py), seed 1, default params except "
    "environment field 50 uT, inclination 60 deg, declination 0 (the conformance field); "
    "ideal sensors from scenario.truth(t) at 200 Hz")


def _counts(value: float, per_count: float) -> int:
    return round(float(value) / per_count)


def make(out: Path) -> None:
    scenario = load_registry().scenarios.get("rc-flight")(PARAMS, seed=1)
    counts = [
        "# high-g input for the Freescale filters: " + HEADER_COMMON,
        "# fast rows 3120..3679 of that run (t = 15.600 .. 18.395 s: 0.4 s of cruise, then the "
        "first 2.4 s of the loop, which starts at 16.0 s); idx counts from 0 at the slice "
        "start, t_s is scenario time",
        "# int16 counts, body NED: accel = -specific force / 9.80665 m/s^2 (gravity positive) "
        "* 2048, gyro deg/s * 128, mag uT * 16, each rounded to nearest",
        "idx,t_s,ax,ay,az,gx,gy,gz,mx,my,mz",
    ]
    truth = ["# true attitude at the Kalman rows of fsl_highg_counts.csv: " + HEADER_COMMON,
             "# quaternion scalar first, body -> NED",
             "idx,t_s,qw,qx,qy,qz"]
    for idx, row in enumerate(range(FIRST, LAST + 1)):
        t_s = row / RATE_HZ
        s = scenario.truth(t_s)
        acc = [_counts(-f / G, 1 / 2048) for f in s.specific_force_body_m_s2]
        gyr = [_counts(w * 180.0 / 3.141592653589793, 1 / 128)
               for w in s.angular_rate_body_rad_s]
        mag = [_counts(b, 1 / 16) for b in s.magnetic_field_body_ut]
        counts.append(",".join([str(idx), f"{t_s:.3f}", *map(str, acc + gyr + mag)]))
        if idx % OVERSAMPLE == OVERSAMPLE - 1:
            q = s.q_body_to_ned
            truth.append(",".join([str(idx), f"{t_s:.3f}", *(f"{v:.9f}" for v in q)]))
    (out / "fsl_highg_counts.csv").write_text("\n".join(counts) + "\n")
    (out / "fsl_highg_truth.csv").write_text("\n".join(truth) + "\n")


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("out", type=Path)
    parser.add_argument("--check", action="store_true",
                        help="compare with tests/data/filters and report differences")
    args = parser.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)
    make(args.out)
    if not args.check:
        return 0
    committed = Path(__file__).resolve().parents[3] / "tests" / "data" / "filters"
    same = True
    for name in ("fsl_highg_counts.csv", "fsl_highg_truth.csv"):
        ok = (args.out / name).read_bytes() == (committed / name).read_bytes()
        print(f"{name}: {'identical' if ok else 'DIFFERS'}")
        same &= ok
    return 0 if same else 1


if __name__ == "__main__":
    sys.exit(main())
