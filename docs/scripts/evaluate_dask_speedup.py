"""Speed-up of ``imuhal evaluate`` on Dask against the serial run, by worker count.

Writes N synthetic BROAD-format trials (tests/support/broad_synthetic.py; never BROAD's data)
into a temporary folder, evaluates them with madgwick (9- and 6-DOF) serially and on a local
Dask cluster of 1, 2, ... workers, checks that every Dask run gives the serial numbers, and
prints the wall times as ratios to the serial run measured in the same process.

    python docs/scripts/evaluate_dask_speedup.py --trials 8 --seconds 20 --workers 1 2
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

from tests.support.broad_synthetic import synthetic_trial, write_hdf5

from imuhal.evaluate.dask_runner import evaluate_dask
from imuhal.evaluate.recording import RecordingSource
from imuhal.evaluate.runner import EstimatorSpec, evaluate_serial
from imuhal.plugins import load_registry


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--trials", type=int, default=8)
    ap.add_argument("--seconds", type=float, default=20.0)
    ap.add_argument("--workers", type=int, nargs="+", default=[1, 2])
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        sources = [RecordingSource(str(write_hdf5(Path(tmp) / f"t{i:02d}.hdf5",
                                                  synthetic_trial(args.seconds, seed=i))))
                   for i in range(args.trials)]
        specs = [EstimatorSpec("madgwick", {}, 9), EstimatorSpec("madgwick", {}, 6)]
        t0 = time.perf_counter()
        serial = evaluate_serial(sources, specs, load_registry())
        t_serial = time.perf_counter() - t0
        key = [(r.trial, r.label, r.dof, r.total_deg, r.inclination_deg) for r in serial]
        print(f"{len(key)} jobs ({args.trials} trials x {len(specs)} settings), "
              f"serial {t_serial:.1f} s")
        for n in args.workers:
            t0 = time.perf_counter()
            res = evaluate_dask(sources, specs, workers=n)
            t = time.perf_counter() - t0
            same = key == [(r.trial, r.label, r.dof, r.total_deg, r.inclination_deg)
                           for r in res]
            print(f"dask {n} worker(s): {t:.1f} s, speed-up {t_serial / t:.2f}x vs serial, "
                  f"identical results: {same}")


if __name__ == "__main__":
    main()
