"""The metric and reader reproduce BROAD's published per-trial results for its example filter.

BROAD's example code ran the x-io Madgwick AHRS (beta 0.1, started from the first sample's
accelerometer and magnetometer) over every trial; its per-trial RMSEs are copied in
tests/data (numbers only). imuhal's madgwick with ``preset: reference``, an exact square
root and the same start is that filter, so evaluating it must give the published numbers.
The data set itself is never in the repository: the test runs when BROAD trials are in
``$IMUHAL_BROAD_DIR`` (e.g. after ``imuhal evaluate --download-broad``) and skips otherwise.
"""

from __future__ import annotations

import json
import os
from pathlib import Path

import pytest

pytest.importorskip("h5py")
pytest.importorskip("scipy")

from imuhal.evaluate.recording import RecordingSource
from imuhal.evaluate.runner import EstimatorSpec, run_job
from imuhal.plugins import load_registry

PUBLISHED = json.loads((Path(__file__).parent.parent / "data" /
                        "broad_published_madgwick_beta0.1.json").read_text())
BROAD_DIR = os.environ.get("IMUHAL_BROAD_DIR")


def _available(limit: int = 2) -> list[Path]:
    if not BROAD_DIR:
        return []
    found = []
    for name in PUBLISHED["trials"]:
        for suffix in (".hdf5", ".mat"):
            p = Path(BROAD_DIR) / f"{name}{suffix}"
            if p.is_file():
                found.append(p)
                break
    return found[:limit]


@pytest.mark.slow
@pytest.mark.skipif(not _available(), reason="BROAD not available: set IMUHAL_BROAD_DIR to a "
                    "folder of its trials (imuhal evaluate --download-broad fills one)")
@pytest.mark.parametrize("path", _available(), ids=lambda p: p.stem)
def test_madgwick_reference_reproduces_the_published_errors(path):
    spec = EstimatorSpec("madgwick", {"preset": "reference", "initial_attitude": "first_sample",
                                      "inv_sqrt": "exact", "beta": PUBLISHED["beta"]}, 9)
    r = run_job(RecordingSource(str(path)).load(), spec, load_registry())
    pub = PUBLISHED["trials"][path.stem]
    assert r.total_deg == pytest.approx(pub["total_rmse_deg"], abs=0.005)
    assert r.heading_deg == pytest.approx(pub["heading_rmse_deg"], abs=0.005)
    assert r.inclination_deg == pytest.approx(pub["inclination_rmse_deg"], abs=0.005)
