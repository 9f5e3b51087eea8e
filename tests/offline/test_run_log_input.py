"""``imuhal estimate`` reads the log ``imuhal run --output LOG --samples`` writes."""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np
import pytest
import yaml

from imuhal.cli.main import main


def _rows(path: Path) -> list[dict[str, str]]:
    with path.open(newline="") as f:
        return list(csv.DictReader(f))


def _ahrs() -> list[str]:
    """The gy91 profile's own ahrs as ``imuhal estimate`` arguments: its estimator's name and
    a --set for each of its settings."""
    ahrs = yaml.safe_load(Path("profiles/gy91.yaml").read_text())["estimators"]["ahrs"]
    args = [ahrs["estimator"]]
    for key, value in ahrs.get("settings", {}).items():
        text = ",".join(map(str, value)) if isinstance(value, list) else \
            "null" if value is None else str(value)
        args += ["--set", f"{key}={text}"]
    return args


@pytest.fixture(scope="module")
def run_log(tmp_path_factory: pytest.TempPathFactory) -> Path:
    log = tmp_path_factory.mktemp("runlog") / "gy91.csv"
    assert main(["run", "profiles/gy91.yaml", "--emulate", "thermal", "--duration", "6",
                 "--quiet", "--output", str(log), "--samples"]) == 0
    return log


def test_an_attitude_estimator_over_a_run_log_reproduces_the_live_estimates(
        run_log: Path, tmp_path: Path) -> None:
    out = tmp_path / "attitude.csv"
    assert main(["estimate", *_ahrs(), str(run_log), "-o", str(out)]) == 0
    live = [r for r in _rows(run_log) if r["source"] == "ahrs"]
    offline = _rows(out)
    assert len(offline) == len(live) > 500
    for name in ("qw", "qx", "qy", "qz", "roll_deg"):
        got = np.array([float(r[name]) for r in offline])
        want = np.array([float(r[name]) for r in live])
        # The log stamps samples to the microsecond (t_s, 6 decimals) and the AHRS's step
        # lengths come from the stamps. Polls on the chip's own grid fall between whole
        # microseconds, and the rounded step lengths (up to 1 us of 5 ms, 2e-4 of a step's
        # rotation) move the quaternion by up to 2e-7 over these 6 s (measured; 1e-6 is
        # 1e-4 deg). With nanosecond stamps the difference is 0 after the first estimate.
        bound = 1e-4 if name == "roll_deg" else 1e-6  # deg; quaternion components
        assert np.max(np.abs(got - want)) < bound, name


def test_a_vario_filter_over_a_run_log_follows_the_live_altitude(
        run_log: Path, tmp_path: Path) -> None:
    out = tmp_path / "vario.csv"
    assert main(["estimate", "vario-kf3", str(run_log), "-o", str(out)]) == 0
    # the vario's start-up withholds its first rows (flags UNSETTLED, no altitude)
    live = {r["t_s"]: float(r["altitude_m"]) for r in _rows(run_log)
            if r["source"] == "vario" and r["altitude_m"]}
    offline = _rows(out)
    assert len(offline) > 100
    assert set(offline[0]) >= {"t_s", "altitude_m", "climb_m_s", "accel_bias_m_s2"}
    last = offline[-1]
    assert abs(float(last["altitude_m"]) - live[f"{float(last['t_s']):.6f}"]) < 0.05


def test_flagged_samples_and_rows_without_columns_are_skipped_not_fused(tmp_path: Path,
                                                            capsys: pytest.CaptureFixture[str]
                                                            ) -> None:
    log = tmp_path / "log.csv"
    header = ["t_s", "source", "kind", "flags", "ax_m_s2", "ay_m_s2", "az_m_s2",
              "gx_rad_s", "gy_rad_s", "gz_rad_s"]
    with log.open("w", newline="") as f:
        w = csv.writer(f)
        w.writerow(header)
        for i in range(20):
            t = f"{i * 0.005:.6f}"
            flags = "2" if i == 10 else "0"  # an overflowed accelerometer sample
            az = "nan" if i == 10 else "-9.80665"
            w.writerow([t, "imu", "accel", flags, "0", "0", az, "", "", ""])
            w.writerow([t, "imu", "gyro", "0", "", "", "", "0", "0", "0"])
            w.writerow([t, "gnss", "velocity", "0", "", "", "", "", "", ""])  # no columns
    out = tmp_path / "out.csv"
    assert main(["estimate", "madgwick", str(log), "-o", str(out)]) == 0
    assert "1 flagged skipped" in capsys.readouterr().err
    assert all(abs(float(r["roll_deg"])) < 1e-9 for r in _rows(out))


def test_a_run_log_without_samples_says_how_to_write_one(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    log = tmp_path / "estimates.csv"
    assert main(["run", "--duration", "2", "--quiet", "--output", str(log)]) == 0
    capsys.readouterr()
    assert main(["estimate", "madgwick", str(log), "-o", str(tmp_path / "o.csv")]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0
    assert "no valid samples" in err and "--samples" in err


def test_a_run_log_written_in_another_frame_is_read_back_into_ned(
        run_log: Path, tmp_path: Path) -> None:
    enu_log = tmp_path / "enu.csv"
    assert main(["run", "profiles/gy91.yaml", "--emulate", "thermal", "--duration", "6",
                 "--quiet", "--output", str(enu_log), "--samples", "--output-frame", "enu"]) == 0
    assert "ax_m_s2_enu" in enu_log.read_text().splitlines()[0]
    from_ned, from_enu = tmp_path / "a.csv", tmp_path / "b.csv"
    for log, out in ((run_log, from_ned), (enu_log, from_enu)):
        assert main(["estimate", *_ahrs(), str(log), "-o", str(out)]) == 0
    a, b = _rows(from_ned), _rows(from_enu)
    assert len(a) == len(b) > 500
    for name in ("qw", "qx", "qy", "qz"):
        got = np.array([float(r[name]) for r in b])
        want = np.array([float(r[name]) for r in a])
        assert np.max(np.abs(got - want)) < 1e-12, name
