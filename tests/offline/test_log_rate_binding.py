"""``imuhal estimate`` has no chip to read a rate back from: it measures the gyro rate from the
log's time stamps and binds the estimators with it, as the pipeline binds the chip's streams.
Defaults follow the data; a fixed-rate setting contradicting it by > 5 % is a one-line error
(exit 2) naming the option."""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np
import pytest

from imuhal.cli.main import main
from imuhal.offline.csv_input import read_sample_csv
from imuhal.offline.log_streams import measured_gyro_streams, table_streams
from imuhal.plugins.manager import load_registry

RATE_HZ = 250.0


def _still_log(path: Path, rows: int = 200, rate_hz: float = RATE_HZ) -> None:
    with path.open("w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["t_s", "gx_rad_s", "gy_rad_s", "gz_rad_s", "ax_m_s2", "ay_m_s2", "az_m_s2"])
        for i in range(rows):
            w.writerow([f"{i / rate_hz:.6f}", 0.0, 0.0, 0.01, 0.0, 0.0, -9.80665])


def test_the_rate_is_the_median_interval_so_a_gap_does_not_move_it() -> None:
    t = np.r_[np.arange(100) / RATE_HZ, 1.0 + np.arange(100) / RATE_HZ]  # a 0.6 s gap
    (gyro,) = measured_gyro_streams(t)
    assert gyro.rate_hz == pytest.approx(RATE_HZ)


def test_too_few_rows_give_no_stream() -> None:
    assert measured_gyro_streams(np.array([0.0, 0.004])) == ()


def test_freescale_defaults_follow_the_logs_rate(tmp_path: Path) -> None:
    src = tmp_path / "imu.csv"
    _still_log(src)
    est = load_registry().estimators.get("freescale-6dof")()
    est.bind(table_streams(read_sample_csv(src)))
    assert est.settings.sensor_rate_hz == pytest.approx(RATE_HZ)  # type: ignore[attr-defined]


def test_a_fixed_rate_contradicting_the_log_is_a_one_line_error(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    src, out = tmp_path / "imu.csv", tmp_path / "out.csv"
    _still_log(src)
    code = main(["estimate", "freescale-6dof", str(src), "--output", str(out),
                 "--set", "sensor_rate_hz=200"])
    err = capsys.readouterr().err.strip()
    assert code == 2 and not out.exists()
    assert "--set sensor_rate_hz: 200 Hz contradicts the gyro stream" in err
    assert len(err.splitlines()) == 1


def test_a_fixed_period_agreeing_with_the_log_runs(tmp_path: Path) -> None:
    src, out = tmp_path / "imu.csv", tmp_path / "out.csv"
    _still_log(src)
    assert main(["estimate", "madgwick", str(src), "--output", str(out),
                 "--set", "sample_period_s=0.0041"]) == 0
