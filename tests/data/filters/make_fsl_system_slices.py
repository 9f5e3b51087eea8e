"""Provenance of the Freescale ANDROID / WIN8 conformance slices (run by hand:
``python make_fsl_system_slices.py CONFORMANCE_DIR``, the folder holding inputs/ and outputs/).

For each system: the first 20 s (4000 rows, 200 Hz) of ``inputs/imu_A_<system>.csv`` as int16
counts (accel 1/2048 g, gyro 1/128 deg/s, mag 1/16 uT, in that build's sensor axes and
accelerometer sign; the script checks every value is an exact count), and the first 500
Kalman rows of ``outputs/fsl_{9dof_gby,6dof_gy}_kalman_A_<system>.csv`` verbatim.
"""

from __future__ import annotations

import csv
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
N_ROWS = 4000
N_KALMAN = 500
SCALES = {"ax_g": 2048, "ay_g": 2048, "az_g": 2048, "gx_dps": 128, "gy_dps": 128,
          "gz_dps": 128, "mx_uT": 16, "my_uT": 16, "mz_uT": 16}


def _counts(src: Path, dst: Path, system: str) -> None:
    with src.open(newline="") as f:
        rows = list(csv.DictReader(f))[:N_ROWS]
    with dst.open("w", newline="") as f:
        f.write(f"# first 20 s of conformance inputs/imu_A_{system}.csv as int16 counts: accel "
                "1/2048 g, gyro 1/128 deg/s, mag 1/16 uT; the build's sensor axes and sign\n")
        w = csv.writer(f, lineterminator="\n")
        w.writerow(["idx", "ax", "ay", "az", "gx", "gy", "gz", "mx", "my", "mz"])
        for r in rows:
            out = [r["idx"]]
            for col, scale in SCALES.items():
                v = float(r[col]) * scale
                if v != round(v):
                    raise SystemExit(f"{src}: idx {r['idx']} {col} is not a whole count")
                out.append(str(round(v)))
            w.writerow(out)


def main(root: Path) -> None:
    for system in ("android", "win8"):
        _counts(root / "inputs" / f"imu_A_{system}.csv",
                HERE / f"fsl_imu_A_{system}_counts.csv", system)
        for name in ("fsl_9dof_gby_kalman_A", "fsl_6dof_gy_kalman_A"):
            lines = (root / "outputs" / f"{name}_{system}.csv").read_text().splitlines()
            (HERE / f"{name}_{system}_first20s.csv").write_text(
                "\n".join(lines[:N_KALMAN + 1]) + "\n")


if __name__ == "__main__":
    main(Path(sys.argv[1]))
