"""Provenance of the AHRS test slices: cuts them from the conformance vectors (run by hand:
``python make_ahrs_slices.py CONFORMANCE_DIR``, the folder holding inputs/ and outputs/).

Inputs keep the columns the filters need; reference outputs keep the quaternion (and the gate
flag). Rows 0..N-1 so that a filter started from its documented initial state can be checked
row by row; the mid-flight slice also keeps the reference quaternion of the row before it.
"""

from __future__ import annotations

import csv
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
N_ROWS = 1400  # 5 s static + 2 s of the motion ramp at 200 Hz
MID = (6000, 6400)  # large rates, yaw through north

INPUT_COLS = ["idx", "t_s", "ax_g", "ay_g", "az_g", "gx_rads", "gy_rads", "gz_rads",
              "mx_uT", "my_uT", "mz_uT"]
TRUTH_COLS = ["idx", "t_s", "qw", "qx", "qy", "qz"]
Q_COLS = ["idx", "q0", "q1", "q2", "q3"]
OUTPUTS = {
    "madgwick_xio_exact_9dof_A.csv": Q_COLS,
    "madgwick_xio_exact_6dof_A.csv": Q_COLS,
    "madgwick_xio_fast_9dof_A.csv": Q_COLS,
    "madgwick_xio_fast_6dof_A.csv": Q_COLS,
    "hari_madgwick_gated_A.csv": [*Q_COLS, "use_accel"],
    "imufilter_A.csv": Q_COLS,
}


def _cut(src: Path, dst: Path, cols: list[str], rows: range) -> None:
    with src.open() as f, dst.open("w", newline="") as g:
        reader = csv.DictReader(f)
        writer = csv.writer(g, lineterminator="\n")
        writer.writerow(cols)
        for i, row in enumerate(reader):
            if i in rows:
                writer.writerow([row[c] for c in cols])


def main() -> None:
    if len(sys.argv) != 2:
        sys.exit("usage: make_ahrs_slices.py CONFORMANCE_DIR")
    conformance = Path(sys.argv[1])
    head = range(N_ROWS)
    mid = range(MID[0], MID[1])
    mid_with_prior = range(MID[0] - 1, MID[1])
    _cut(conformance / "inputs/imu_A.csv", HERE / "imu_A_head.csv", INPUT_COLS, head)
    _cut(conformance / "inputs/imu_truth.csv", HERE / "imu_A_truth_head.csv", TRUTH_COLS, head)
    _cut(conformance / "inputs/imu_A.csv", HERE / "imu_A_mid.csv", INPUT_COLS, mid)
    for name, cols in OUTPUTS.items():
        prefix = "imufilter" if name.startswith("imufilter") else (
            "hari" if name.startswith("hari") else "madgwick")
        stem = name.removesuffix(".csv")
        if not stem.startswith(prefix):
            stem = f"{prefix}_{stem}"
        _cut(conformance / "outputs" / name, HERE / f"{stem}_head.csv", cols, head)
    _cut(conformance / "outputs/madgwick_xio_exact_9dof_A.csv",
         HERE / "madgwick_xio_exact_9dof_A_mid.csv", Q_COLS, mid_with_prior)


if __name__ == "__main__":
    sys.exit(main())
