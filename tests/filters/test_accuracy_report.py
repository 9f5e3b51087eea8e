"""docs/scripts/estimator_accuracy.py: its error measures, and its tables on short runs.

The full report takes minutes; here each function runs on a few simulated seconds (seed 1)
and the tables it builds are checked for the documented columns (those in
docs/estimators.md) and finite numbers. Error measures are checked on exact rotations to
1e-6 deg.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from tests.support.docs_scripts import load_docs_script

from imuhal.core.frames import quat_from_euler_deg
from imuhal.plugins.manager import Registry, load_registry

ROOT = Path(__file__).resolve().parents[2]
DASH = "—"


ea = load_docs_script("estimator_accuracy")


@pytest.fixture(scope="module")
def registry() -> Registry:
    return load_registry()


def _cells(line: str) -> list[str]:
    return [c.strip() for c in line.strip().strip("|").split("|")]


def _body(table: str) -> list[list[str]]:
    return [_cells(line) for line in table.splitlines()[2:]]


def test_attitude_errors_separate_heading_from_tilt() -> None:
    truth = np.array([quat_from_euler_deg(0, 0, 0)] * 3)
    est = np.array([quat_from_euler_deg(0, 0, 30), quat_from_euler_deg(10, 0, 0),
                    quat_from_euler_deg(0, -7, 0)])
    total, tilt = ea.attitude_errors_deg(est, truth)
    np.testing.assert_allclose(total, [30.0, 10.0, 7.0], atol=1e-6)
    np.testing.assert_allclose(tilt, [0.0, 10.0, 7.0], atol=1e-6)


def test_attitude_error_ignores_quaternion_sign() -> None:
    q = np.array([quat_from_euler_deg(20, -40, 170)])
    total, tilt = ea.attitude_errors_deg(-q, q)
    assert total[0] == pytest.approx(0.0, abs=1e-5) and tilt[0] == pytest.approx(0.0, abs=1e-5)


def test_crossing_time_interpolates_and_handles_both_directions() -> None:
    t = np.arange(0.0, 5.0, 0.5)
    ramp = np.clip(t - 1.0, 0.0, 2.0)           # 0 until 1 s, then 1 m/s^2 to 2 m/s
    assert ea.crossing_time_s(t, ramp, 0.8, 0.0) == pytest.approx(1.8)
    assert ea.crossing_time_s(t, -ramp, -0.8, 0.0) == pytest.approx(1.8)
    assert ea.crossing_time_s(t, ramp, 5.0, 0.0) is None


def test_replace_block_rewrites_only_between_the_markers() -> None:
    text = f"head\n{ea.START_MARK}\nold\n{ea.END_MARK}\ntail\n"
    once = ea.replace_block(text, "new table")
    assert once == f"head\n{ea.START_MARK}\nnew table\n{ea.END_MARK}\ntail\n"
    assert ea.replace_block(once, "new table") == once


def test_short_attitude_runs_fill_every_documented_column(registry: Registry) -> None:
    base = ea.seed_profile(registry)
    names = ["madgwick", "freescale-6dof"]
    rows = []
    for cond in ea.Condition:  # no accel/mag records here: the full run measures them
        prof = ea.condition_profile(ea.ahrs_profile(base, names), cond, {})
        rows += ea.measure_attitude(prof, registry, "tumble", 3.0, cond, settle_s=1.0)
    table = ea.attitude_table(rows)
    assert _cells(table.splitlines()[0]) == list(ea.ATTITUDE_COLUMNS)
    body = _body(table)
    assert [r[:2] for r in body] == [["madgwick", "tumble"], ["freescale-6dof", "tumble"]]
    total_columns = {2, 5, 7}
    for row in body:
        six_dof = row[0] in ea.SIX_DOF
        for i, cell in enumerate(row[2:], start=2):
            if six_dof and i in total_columns:
                assert cell == DASH, f"{row[0]}: heading is unobservable, got {cell}"
            else:
                assert math.isfinite(float(cell)), f"{row[0]} column {i}: {cell}"


def test_short_vario_run_reports_every_vertical_estimator(registry: Registry) -> None:
    base = ea.seed_profile(registry)
    prof = ea.condition_profile(ea.vario_profile(base, 0.01), ea.Condition.GYRO_STARTUP, {})
    rows = ea.measure_vario(prof, registry, "thermal", 3.0, settle_s=1.0)
    assert sorted(r.estimator for r in rows) == sorted(ea.VARIO_LABELS.values())
    table = ea.vario_table(rows)
    assert _cells(table.splitlines()[0]) == list(ea.VARIO_COLUMNS)
    for row in _body(table):
        assert math.isfinite(float(row[2])) and math.isfinite(float(row[3]))
        assert row[4] == row[5] == DASH  # step delays only on the step scenario


def test_docs_table_has_the_columns_the_script_writes() -> None:
    doc = (ROOT / "docs" / "estimators.md").read_text(encoding="utf-8")
    block = doc[doc.index(ea.START_MARK):doc.index(ea.END_MARK)]
    headers = [_cells(line) for line in block.splitlines() if line.startswith("| estimator")]
    assert headers == [list(ea.ATTITUDE_COLUMNS), list(ea.VARIO_COLUMNS)]


def test_conditions_store_only_their_own_calibration(registry: Registry) -> None:
    from imuhal.calibration.model import AccelCalibration, DeviceCalibration

    base = ea.seed_profile(registry)
    records = {"imu": DeviceCalibration(accel=AccelCalibration(offset_m_s2=(0.1, 0.0, 0.0)))}
    cal = {c: ea.condition_profile(base, c, records).devices for c in ea.Condition}
    assert all(d.calibration is None for d in cal[ea.Condition.AS_DELIVERED].values())
    gyro_only = cal[ea.Condition.GYRO_STARTUP]["imu"].calibration
    assert gyro_only is not None and gyro_only.gyro_at_startup is not None
    assert gyro_only.accel is None
    full = cal[ea.Condition.CALIBRATED]["imu"].calibration
    assert full is not None and full.gyro_at_startup is not None
    assert full.accel == records["imu"].accel
