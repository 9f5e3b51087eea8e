"""``imuhal estimate`` over a log's blocks writes what the per-sample path writes.

``imuhal estimate`` and ``evaluate`` hand an AHRS each chunk of a log as blocks (one per
quantity): as columns (``attitude_rows``) or, through the pipeline's router, as estimates
(``update_blocks``); the reference is the same rows fed sample by sample through
``process()`` in fusion order. On conformance data set A, with the log's awkward cases added
(a slower and a missing magnetometer, values beyond the full scale, a time jump, a repeated
timestamp, an accelerometer that goes stale), every written cell equals the reference to
1e-12 and the estimator ends in the same state, so chunks chain. Run compiled (numba's JIT,
the AOT extension) and with ``IMUHAL_NO_JIT=1`` (the Python steps).
"""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np
import pytest
from tests.filters.dataset_a import load_head

from imuhal.offline.chain import instants_in_fusion_order
from imuhal.offline.csv_input import ACCEL, GYRO, MAG, TIME, SampleTable
from imuhal.offline.csv_output import EstimateCsvWriter
from imuhal.offline.runner import feed, imu_events, iter_offline, run_offline
from imuhal.plugins.manager import load_registry

CASES = [
    ("madgwick", {}),
    ("madgwick", {"preset": "seed"}),
    ("madgwick", {"preset": "reference"}),
    ("madgwick", {"use_mag": False, "max_aux_age_s": 0.02}),
    ("madgwick", {"dt_from_timestamps": False, "turn_compensation": False}),
    ("madgwick", {"nominal_airspeed_m_s": 10.0}),  # turn compensated in the column path too
    ("mahony", {}),
    ("mahony", {"ki": 0.2, "accel_gate_g": (0.8, 1.2)}),
    ("imufilter", {}),
    ("decoupled", {}),
    ("vqf", {}),
]


def _table(with_mag: bool = True) -> SampleTable:
    t, gyro, accel, mag, _ = load_head()
    t, gyro, accel, mag = t[:1500].copy(), gyro[:1500].copy(), accel[:1500].copy(), mag[:1500]
    mag = mag.copy()
    mag[1::3] = np.nan              # a slower magnetometer
    mag[300:380] = np.nan           # the magnetometer goes quiet: held, then stale
    mag[5, 1] = np.inf              # an impossible magnetometer value
    gyro[500, 1] = 1e9              # an impossible gyro value: no step, counted
    accel[600, 2] = 1e6             # an impossible accel value: the held one is used
    accel[700:760] = (0.0, 0.0, 1e5)  # 60 impossible accel rows: the held one goes stale
    accel[800] = (0.0, 0.0, -25.0)  # 2.5 g: a hard gate closes
    t[900:] += 0.5                  # a time jump: nominal step, counted
    t[1000] = t[999]                # a repeated timestamp: nominal step, counted
    cols = {TIME: t, **{n: gyro[:, i] for i, n in enumerate(GYRO)},
            **{n: accel[:, i] for i, n in enumerate(ACCEL)}}
    if with_mag:
        cols.update({n: mag[:, i] for i, n in enumerate(MAG)})
    return SampleTable(Path("a.csv"), cols, np.arange(2, len(t) + 2))


def _chunks(table: SampleTable, size: int) -> list[SampleTable]:
    n = len(table)
    return [SampleTable(table.path, {k: v[i:i + size] for k, v in table.columns.items()},
                        table.lines[i:i + size]) for i in range(0, n, size)]


def _written(path: Path, chunks: list) -> list[list[str]]:
    writer = EstimateCsvWriter(path)
    for chunk in chunks:
        writer.write(chunk)
    writer.commit()
    with path.open(newline="") as f:
        return list(csv.reader(f))


def _same_cells(rows: list[list[str]], ref: list[list[str]]) -> None:
    assert rows[0] == ref[0]
    assert len(rows) == len(ref)
    for row, ref_row in zip(rows[1:], ref[1:], strict=True):
        for cell, ref_cell in zip(row, ref_row, strict=True):
            if cell == ref_cell:
                continue
            assert float(cell) == pytest.approx(float(ref_cell), rel=1e-12, abs=1e-12)


def _run(name: str, settings: dict, tmp_path: Path, chunk: int, with_mag: bool = True
         ) -> None:
    if name == "vqf":
        pytest.importorskip("vqf", reason="the vqf package is not installed")
    registry = load_registry()
    cls = registry.estimators.get(name)
    table = _table(with_mag)
    ref_est = cls(cls.Settings(**settings))
    # each chunk is one fusion step: its samples in fusion order (a time stamp repeated
    # across two chunks keeps the row order)
    ref = _written(tmp_path / "ref.csv",
                   [feed(ref_est, instants_in_fusion_order(imu_events(c)))
                    for c in _chunks(table, chunk)])
    ref_state = ref_est.get_state()
    for columnar in (True, False):
        est = cls(cls.Settings(**settings))
        chunks = list(iter_offline(est, _chunks(table, chunk), columnar=columnar))
        # the column path was taken, or the estimates
        assert all(isinstance(c, list) is not columnar for c in chunks)
        _same_cells(_written(tmp_path / f"rows-{columnar}.csv", chunks), ref)
        state = est.get_state()
        assert state["counters"] == ref_state["counters"]
        assert state["q"] == pytest.approx(ref_state["q"], abs=1e-12)
        for key in ("last_gyro_t_ns", "accel_m_s2", "accel_t_ns", "mag_ut", "mag_t_ns",
                    "aligned"):
            assert state[key] == ref_state[key], key


@pytest.mark.parametrize(("name", "settings"), CASES,
                         ids=[f"{n}-{','.join(map(str, s.values())) or 'defaults'}"
                              for n, s in CASES])
def test_column_path_writes_what_the_sample_path_writes(
        name: str, settings: dict, tmp_path: Path, compiled_backend: str) -> None:
    _run(name, settings, tmp_path, chunk=211)


@pytest.mark.parametrize(("name", "settings"), CASES[:1] + CASES[6:7],
                         ids=["madgwick", "mahony"])
def test_column_path_without_numba_writes_what_the_sample_path_writes(
        name: str, settings: dict, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("IMUHAL_NO_JIT", "1")
    _run(name, settings, tmp_path, chunk=211)


def test_a_6dof_log_runs_the_column_path_like_the_sample_path(tmp_path: Path) -> None:
    _run("madgwick", {}, tmp_path, chunk=500, with_mag=False)


def test_one_row_chunks_chain_like_the_sample_path(tmp_path: Path) -> None:
    """The state handed from chunk to chunk (held samples, last gyro time) is complete."""
    _run("mahony", {}, tmp_path, chunk=1)


def test_the_log_exercises_every_case_the_rows_resolve() -> None:
    """The comparisons above cannot pass by missing a case: the reference meets each one."""
    registry = load_registry()
    est = registry.estimators.get("madgwick")()
    run_offline(est, _table())
    counters = est.get_state()["counters"]
    assert counters["stale_accel"] > 0
    assert counters["stale_mag"] > 0
    assert counters["dt_fallbacks"] == 2
    assert counters["beyond_full_scale"] == {"gyro": 1, "accel": 61, "mag": 1}
