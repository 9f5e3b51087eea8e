"""``imuhal estimate``: any estimator over a CSV log, reproducing the reference outputs, and
bad input rejected with the row and column named."""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np
import pytest

from imuhal.cli.main import main

DATA = Path(__file__).resolve().parents[1] / "data" / "filters"
G = 9.80665
ROWS = 400


def _conformance_input(path: Path) -> None:
    """imu_A (gravity-positive g, rad/s, uT) as project-unit columns (specific force m/s^2)."""
    with (DATA / "imu_A_head.csv").open() as f, path.open("w", newline="") as out:
        writer = csv.writer(out)
        writer.writerow(["t_s", "gx_rad_s", "gy_rad_s", "gz_rad_s", "ax_m_s2", "ay_m_s2",
                         "az_m_s2", "mx_ut", "my_ut", "mz_ut"])
        for i, r in enumerate(csv.DictReader(f)):
            if i == ROWS:
                break
            writer.writerow([r["t_s"], r["gx_rads"], r["gy_rads"], r["gz_rads"],
                             *(-float(r[k]) * G for k in ("ax_g", "ay_g", "az_g")),
                             r["mx_uT"], r["my_uT"], r["mz_uT"]])


def _read(path: Path) -> dict[str, np.ndarray]:
    with path.open() as f:
        rows = list(csv.DictReader(f))
    # a withheld estimate's row (the vertical filters' start-up: flags UNSETTLED) has empty
    # cells: NaN here
    return {k: np.array([float(r[k]) if r[k] != "" else np.nan for r in rows])
            for k in rows[0]}


def test_madgwick_over_a_log_matches_the_x_io_reference(tmp_path: Path) -> None:
    src, out = tmp_path / "imu.csv", tmp_path / "out.csv"
    _conformance_input(src)
    assert main(["estimate", "madgwick", str(src), "--output", str(out),
                 "--set", "preset=reference", "--set", "inv_sqrt=exact",
                 "--set", "dt_from_timestamps=false"]) == 0
    got = _read(out)
    ref = _read(DATA / "madgwick_xio_exact_9dof_A_head.csv")
    q = np.column_stack([got[k] for k in ("qw", "qx", "qy", "qz")])
    q_ref = np.column_stack([ref[k][:ROWS] for k in ("q0", "q1", "q2", "q3")])
    assert np.max(np.abs(q - q_ref)) < 1e-5
    assert {"roll_deg", "pitch_deg", "yaw_deg"} <= set(got)


def test_vario_kf3_over_altitude_and_vertical_acceleration(tmp_path: Path) -> None:
    src, out = tmp_path / "vario.csv", tmp_path / "out.csv"
    with (DATA / "vario_C_first50s.csv").open() as f, src.open("w", newline="") as o:
        w = csv.writer(o)
        w.writerow(["t_s", "altitude_m", "accel_up_m_s2"])
        for i, r in enumerate(csv.DictReader(f)):
            w.writerow([i * 0.025, float(r["z_baro_cm"]) / 100, float(r["a_meas_cms2"]) / 100])
    assert main(["estimate", "vario-kf3", str(src), "--output", str(out)]) == 0
    got = _read(out)
    # the start-up's withheld rows add the flags column (docs/estimators.md)
    assert [c for c in got if c != "flags"][:4] == ["t_s", "altitude_m", "climb_m_s",
                                                    "accel_bias_m_s2"]
    truth = _read(DATA / "vario_C_first50s.csv")
    late = got["t_s"] > 10
    n = len(got["t_s"])
    true_v = truth["v_true_cms"][-n:][late] / 100
    assert float(np.sqrt(np.mean((got["climb_m_s"][late] - true_v) ** 2))) < 0.3


def _vertical_csv(path: Path) -> None:
    """Data set C's first 50 s (40 Hz) as the vertical CSV form."""
    with (DATA / "vario_C_first50s.csv").open() as f, path.open("w", newline="") as o:
        w = csv.writer(o)
        w.writerow(["t_s", "altitude_m", "accel_up_m_s2"])
        for i, r in enumerate(csv.DictReader(f)):
            w.writerow([i * 0.025, float(r["z_baro_cm"]) / 100, float(r["a_meas_cms2"]) / 100])


@pytest.mark.parametrize(("mode", "tag"), [("esp32", "esp32"), ("avario", "avario"),
                                           ("y2021", "2021")])
def test_vario_kf3_estimate_steps_on_the_first_sample_as_the_references_do(
        tmp_path: Path, mode: str, tag: str) -> None:
    """Every row after the first matches the reference (issue 10: the first sample's
    predict/update used to be skipped: up to 68 cm/s off early, 0.88 cm/s after 5 s)."""
    src, out = tmp_path / "vario.csv", tmp_path / "out.csv"
    _vertical_csv(src)
    assert main(["estimate", "vario-kf3", str(src), "--output", str(out),
                 "--set", "preset=reference", "--set", f"mode={mode}"]) == 0
    got = _read(out)
    ref = _read(DATA / f"vario_kf3_{tag}_C_slices.csv")
    rows = ref["idx"].astype(int)
    later = rows >= 1
    np.testing.assert_allclose(got["altitude_m"][rows[later]] * 100, ref["z_cm"][later],
                               rtol=0, atol=0.1)
    np.testing.assert_allclose(got["climb_m_s"][rows[later]] * 100, ref["v_cms"][later],
                               rtol=0, atol=0.5)


def test_vertical_csv_may_be_multi_rate_with_empty_cells(tmp_path: Path) -> None:
    """500 Hz accelerometer rows and a 50 Hz barometer: each row carries what was measured
    then. The filter sees each barometer interval's mean acceleration, so a climb at 1 m/s^2
    of true acceleration is tracked without pre-averaging."""
    src, out = tmp_path / "multi.csv", tmp_path / "out.csv"
    lines = ["t_s,altitude_m,accel_up_m_s2"]
    for i in range(1, 2001):  # 4 s at 500 Hz; accelerating upwards from t = 1 s
        t = i * 0.002
        a = 1.0 if t >= 1.0 else 0.0
        z = 100.0 + (0.5 * (t - 1.0) ** 2 if t >= 1.0 else 0.0)
        lines.append(f"{t:.3f},{z:.6f},{a}" if i % 10 == 0 else f"{t:.3f},,{a}")
    src.write_text("\n".join(lines) + "\n")
    assert main(["estimate", "vario-kf3", str(src), "--output", str(out)]) == 0
    got = _read(out)
    assert len(got["t_s"]) == 200  # one estimate per barometer sample
    assert got["climb_m_s"][-1] == pytest.approx(3.0, abs=0.05)


def test_vario_estimate_configures_the_ahrs_behind_it(tmp_path: Path) -> None:
    src = tmp_path / "imu.csv"
    _conformance_input(src)
    text = src.read_text().splitlines()
    rows = [text[0] + ",pressure_pa"] + [f"{row},90000" for row in text[1:]]
    src.write_text("\n".join(rows) + "\n")
    outs = []
    for beta in ("0.1", "2.5"):
        out = tmp_path / f"out{beta}.csv"
        assert main(["estimate", "vario-kf3", str(src), "--output", str(out), "--ahrs-set",
                     f"beta={beta}", "--ahrs-set", "sample_period_s=0.005"]) == 0
        outs.append(_read(out)["climb_m_s"])
    assert not np.array_equal(outs[0], outs[1])


def test_a_bad_ahrs_setting_is_a_one_line_error(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    src = _write(tmp_path / "in.csv", HEADER.strip() + ",pressure_pa\n0,0,0,0,0,0,-9.8,90000\n")
    code = main(["estimate", "vario-kf3", str(src), "--output", str(tmp_path / "o.csv"),
                 "--ahrs-set", "betta=1"])
    assert code == 2
    assert "--ahrs-set betta" in capsys.readouterr().err


def test_an_impossible_gyro_value_is_dropped_and_reported(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """Issue 9 item 8: one 1e30 rad/s gyro row used to flip the attitude to the end."""
    src, clean_src = tmp_path / "imu.csv", tmp_path / "clean.csv"
    _conformance_input(clean_src)
    lines = clean_src.read_text().splitlines()
    cells = lines[101].split(",")
    cells[1] = "1e30"
    src.write_text("\n".join([*lines[:101], ",".join(cells), *lines[102:]]) + "\n")
    out, clean_out = tmp_path / "out.csv", tmp_path / "clean_out.csv"
    assert main(["estimate", "madgwick", str(clean_src), "--output", str(clean_out)]) == 0
    capsys.readouterr()
    assert main(["estimate", "madgwick", str(src), "--output", str(out)]) == 0
    assert "1 gyro value(s) beyond the full scale" in capsys.readouterr().err
    got, clean = _read(out), _read(clean_out)
    assert len(got["t_s"]) == len(clean["t_s"]) - 1
    q = np.column_stack([got[k][-50:] for k in ("qw", "qx", "qy", "qz")])
    q_clean = np.column_stack([clean[k][-50:] for k in ("qw", "qx", "qy", "qz")])
    assert np.max(np.abs(q - q_clean)) < 1e-3


def _write(path: Path, text: str) -> Path:
    path.write_text(text)
    return path


HEADER = "t_s,gx_rad_s,gy_rad_s,gz_rad_s,ax_m_s2,ay_m_s2,az_m_s2\n"


@pytest.mark.parametrize(
    ("body", "message"),
    [
        ("0,0,0,0,0,0,-9.8\n0.005,0,0,zero,0,0,-9.8\n", "line 3, column 'gz_rad_s': 'zero'"),
        ("0,0,0,0,0,0,-9.8\n0.005,0,0,0,nan,0,-9.8\n", "line 3, column 'ax_m_s2'"),
        ("0,0,0,0,0,0,-9.8\n0,0,0,0,0,0,-9.8\n", "line 3, column 't_s': time 0 s does not"),
        ("0,0,0,0,0,0\n", "line 2: 6 cells"),
    ],
)
def test_bad_input_names_the_line_and_column(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], body: str, message: str
) -> None:
    src = _write(tmp_path / "in.csv", HEADER + body)
    assert main(["estimate", "madgwick", str(src), "--output", str(tmp_path / "o.csv")]) == 2
    assert message in capsys.readouterr().err


def test_a_missing_column_names_what_is_needed(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    src = _write(tmp_path / "in.csv", "t_s,gx_rad_s\n0,0\n")
    assert main(["estimate", "madgwick", str(src), "--output", str(tmp_path / "o.csv")]) == 2
    err = capsys.readouterr().err
    assert "missing column(s)" in err and "ax_m_s2" in err


def test_a_bad_setting_names_the_key_and_the_settings(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    src = _write(tmp_path / "in.csv", HEADER + "0,0,0,0,0,0,-9.8\n")
    assert main(["estimate", "madgwick", str(src), "--output", str(tmp_path / "o.csv"),
                 "--set", "betta=0.2"]) == 2
    err = capsys.readouterr().err
    assert "--set betta: madgwick has no such setting" in err and "beta" in err


def test_rate_gives_times_when_the_log_has_none(tmp_path: Path) -> None:
    src = _write(tmp_path / "in.csv", "gx_rad_s,gy_rad_s,gz_rad_s,ax_m_s2,ay_m_s2,az_m_s2\n"
                 + "0,0,0,0,0,-9.80665\n" * 10)
    out = tmp_path / "o.csv"
    assert main(["estimate", "mahony", str(src), "--output", str(out), "--rate", "100"]) == 0
    assert _read(out)["t_s"][-1] == pytest.approx(0.09)


def test_without_time_or_rate_the_error_says_what_to_add(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    src = _write(tmp_path / "in.csv", "gx_rad_s,gy_rad_s,gz_rad_s,ax_m_s2,ay_m_s2,az_m_s2\n"
                 "0,0,0,0,0,-9.8\n")
    assert main(["estimate", "mahony", str(src), "--output", str(tmp_path / "o.csv")]) == 2
    assert "missing column 't_s'" in capsys.readouterr().err


def test_vario_from_full_imu_and_pressure_does_the_gravity_compensation(tmp_path: Path) -> None:
    """A level board in an elevator-like climb: IMU at 100 Hz, pressure every 4th row."""
    from imuhal.core.atmosphere import pressure_pa_at_altitude

    src, out = tmp_path / "full.csv", tmp_path / "out.csv"
    t = np.arange(0, 20, 0.01)
    climb = np.clip((t - 5) / 2, 0, 1) * 2.0          # ramps to 2 m/s from t = 5 s to 7 s
    accel_up = np.where((t > 5) & (t < 7), 1.0, 0.0)
    alt = np.cumsum(climb) * 0.01
    with src.open("w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["t_s", "gx_rad_s", "gy_rad_s", "gz_rad_s", "ax_m_s2", "ay_m_s2", "az_m_s2",
                    "pressure_pa"])
        for i, ti in enumerate(t):
            p = pressure_pa_at_altitude(alt[i]) if i % 4 == 0 else ""
            w.writerow([f"{ti:.3f}", 0, 0, 0, 0, 0, -(G + accel_up[i]), p])
    assert main(["estimate", "vario-kf3", str(src), "--output", str(out)]) == 0
    got = _read(out)
    late = got["t_s"] > 12
    assert np.allclose(got["climb_m_s"][late], 2.0, atol=0.05)


def test_a_9dof_filter_on_a_csv_without_magnetometer_columns_is_an_error_not_an_empty_file(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Issue 26 item 8: it exited 0 with "0 estimates" and an empty file."""
    body = "".join(f"{i * 0.01:.2f},0,0,0,0.01,0,-9.81\n" for i in range(100))
    src = _write(tmp_path / "in.csv", HEADER + body)
    out = tmp_path / "o.csv"
    assert main(["estimate", "freescale-9dof", str(src), "--output", str(out)]) == 2
    err = [line for line in capsys.readouterr().err.splitlines() if line]
    assert len(err) == 1 and "made no estimate from 100 rows" in err[0] and "mag" in err[0]
    assert not out.exists()
