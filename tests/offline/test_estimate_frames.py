"""``imuhal estimate --input-frame / --output-frame``: logs in other conventions in, attitudes
in other conventions out, the estimator itself always in NED.

The conversions the tests expect are written out by hand here (axis swaps and sign flips), not
taken from imuhal.core.conventions, so a wrong table there fails these tests.
"""

from __future__ import annotations

import csv
import math
from pathlib import Path

import numpy as np
import pytest

from imuhal.cli.main import main
from imuhal.core.frames import quat_from_euler_deg, quat_to_matrix

DATA = Path(__file__).resolve().parents[1] / "data" / "filters"
G = 9.80665
ROWS = 1400  # 5 s static, then 2 s of motion
HEADER = ["t_s", "gx_rad_s", "gy_rad_s", "gz_rad_s", "ax_m_s2", "ay_m_s2", "az_m_s2",
          "mx_ut", "my_ut", "mz_ut"]

ENU_FROM_NED = np.array([[0.0, 1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, -1.0]])
FLU_FROM_FRD = np.diag([1.0, -1.0, -1.0])


def _dataset_a_rows() -> list[tuple[float, np.ndarray, np.ndarray, np.ndarray]]:
    """Rows of imu_A: t, gyro rad/s, specific force m/s^2 (from gravity-positive g), mag uT;
    all in body NED (forward-right-down)."""
    out = []
    with (DATA / "imu_A_head.csv").open() as f:
        for i, r in enumerate(csv.DictReader(f)):
            if i == ROWS:
                break
            gyro = np.array([float(r[k]) for k in ("gx_rads", "gy_rads", "gz_rads")])
            force = -G * np.array([float(r[k]) for k in ("ax_g", "ay_g", "az_g")])
            mag = np.array([float(r[k]) for k in ("mx_uT", "my_uT", "mz_uT")])
            out.append((float(r["t_s"]), gyro, force, mag))
    return out


def _write(path: Path, rows: list[tuple[float, np.ndarray, np.ndarray, np.ndarray]]) -> Path:
    with path.open("w", newline="") as f:
        w = csv.writer(f)
        w.writerow(HEADER)
        for t, gyro, force, mag in rows:
            w.writerow([t, *map(repr, map(float, (*gyro, *force, *mag)))])
    return path


def _read(path: Path) -> dict[str, np.ndarray]:
    with path.open() as f:
        rows = list(csv.DictReader(f))
    return {k: np.array([float(r[k]) for r in rows]) for k in rows[0]}


def _quats(cols: dict[str, np.ndarray], suffix: str = "") -> np.ndarray:
    return np.column_stack([cols[f"q{c}{suffix}"] for c in "wxyz"])


@pytest.fixture(scope="module")
def runs(tmp_path_factory: pytest.TempPathFactory) -> dict[str, dict[str, np.ndarray]]:
    """madgwick over the same recording: in NED as is, and in ENU/FLU converted by hand
    (FLU = (x, -y, -z) of FRD for every vector; specific force keeps its sign)."""
    tmp = tmp_path_factory.mktemp("frames")
    ned = _dataset_a_rows()
    enu = [(t, g * [1, -1, -1], f * [1, -1, -1], m * [1, -1, -1]) for t, g, f, m in ned]
    src_ned, src_enu = _write(tmp / "ned.csv", ned), _write(tmp / "enu.csv", enu)
    out = {}
    for name, argv in {
        "ned": [str(src_ned)],
        "enu_in": [str(src_enu), "--input-frame", "enu"],
        "enu_in_out": [str(src_enu), "--input-frame", "ros", "--output-frame", "ros"],
    }.items():
        dst = tmp / f"{name}_out.csv"
        assert main(["estimate", "madgwick", *argv, "--output", str(dst)]) == 0
        out[name] = _read(dst)
    return out


def test_enu_input_gives_the_same_ned_attitude_as_the_recording_converted_by_hand(
        runs: dict[str, dict[str, np.ndarray]]) -> None:
    q_ned, q_enu_in = _quats(runs["ned"]), _quats(runs["enu_in"])
    assert len(q_ned) == ROWS
    np.testing.assert_allclose(q_enu_in, q_ned, atol=1e-12)


def test_enu_output_is_the_ned_attitude_with_both_endpoints_re_expressed(
        runs: dict[str, dict[str, np.ndarray]]) -> None:
    """R_enu = E R_ned B^T: E renames NED as ENU, B renames FRD as FLU."""
    q_ned, q_ros = _quats(runs["ned"]), _quats(runs["enu_in_out"], "_enu")
    for a, b in zip(q_ned[::50], q_ros[::50], strict=True):
        np.testing.assert_allclose(quat_to_matrix(b),
                                   ENU_FROM_NED @ quat_to_matrix(a) @ FLU_FROM_FRD.T,
                                   atol=1e-12)


def test_output_header_names_the_frame_of_its_columns(
        runs: dict[str, dict[str, np.ndarray]]) -> None:
    header = list(runs["enu_in_out"])
    assert header[:8] == ["t_s", "qw_enu", "qx_enu", "qy_enu", "qz_enu", "roll_deg_enu",
                          "pitch_deg_enu", "yaw_deg_enu"]
    assert "qw" not in header and "qw" in runs["ned"]


def test_ros_output_of_a_board_pitched_nose_up_30_deg_heading_east(tmp_path: Path) -> None:
    """A still board, nose 30 deg up, forward pointing east; a horizontal 50 uT field (the
    inclination freescale-9dof assumes at start-up, so it has nothing to learn).

    By hand, in ROS terms (ENU earth, FLU body): forward is (cos 30, 0, sin 30) in ENU, left
    is north, so the body is the earth frame turned by -30 deg about north (positive about
    the left axis would lower the nose): q = (cos 15, 0, -sin 15, 0); roll 0, pitch -30
    (ROS pitch is nose down positive), yaw 0 (anticlockwise from east)."""
    q_true = quat_from_euler_deg(0.0, 30.0, 90.0)
    r_t = quat_to_matrix(q_true).T
    force = r_t @ [0.0, 0.0, -G]
    mag = r_t @ [50.0, 0.0, 0.0]
    rows = [(i / 200.0, np.zeros(3), force, mag) for i in range(200)]
    src, dst = _write(tmp_path / "still.csv", rows), tmp_path / "ros.csv"
    # freescale-9dof locks to the eCompass at its second Kalman step: exact from the start
    assert main(["estimate", "freescale-9dof", str(src), "--output", str(dst),
                 "--output-frame", "ros"]) == 0
    got = _read(dst)
    c15, s15 = math.cos(math.radians(15.0)), math.sin(math.radians(15.0))
    q = _quats(got, "_enu")
    q = q * np.sign(q[:, :1])
    np.testing.assert_allclose(q, np.tile([c15, 0.0, -s15, 0.0], (len(q), 1)), atol=1e-6)
    for col, want in (("roll_deg_enu", 0.0), ("pitch_deg_enu", -30.0), ("yaw_deg_enu", 0.0)):
        np.testing.assert_allclose(got[col], want, atol=1e-4)


def test_an_unknown_frame_is_a_one_line_usage_error(tmp_path: Path,
                                                    capsys: pytest.CaptureFixture[str]) -> None:
    src = _write(tmp_path / "in.csv", _dataset_a_rows()[:10])
    with pytest.raises(SystemExit) as exc:
        main(["estimate", "madgwick", str(src), "--output", str(tmp_path / "o.csv"),
              "--input-frame", "nwu"])
    assert exc.value.code == 2
    err = capsys.readouterr().err.strip().splitlines()[-1]
    assert "--input-frame" in err and "'nwu'" in err and "enu" in err
    assert not (tmp_path / "o.csv").exists()


def test_frame_suffixed_columns_say_their_frame_without_the_option(tmp_path: Path) -> None:
    """Columns named as imuhal writes them in another frame (gx_rad_s_enu ...) are read in
    that frame; a slower magnetometer's empty cells stay allowed."""
    rows = [(t, g * [1, -1, -1], f * [1, -1, -1], m * [1, -1, -1])
            for t, g, f, m in _dataset_a_rows()[:400]]
    plain = _write(tmp_path / "plain.csv", rows)
    suffixed = tmp_path / "suffixed.csv"
    lines = plain.read_text().splitlines()
    header = ",".join(h if h == "t_s" else f"{h}_enu" for h in lines[0].split(","))
    body = [",".join([*line.split(",")[:7], "", "", ""]) if i % 2 else line
            for i, line in enumerate(lines[1:])]
    suffixed.write_text("\n".join([header, *body]) + "\n")
    sparse_plain = tmp_path / "sparse_plain.csv"
    sparse_plain.write_text("\n".join([lines[0], *body]) + "\n")
    out_a, out_b = tmp_path / "a.csv", tmp_path / "b.csv"
    assert main(["estimate", "madgwick", str(suffixed), "--output", str(out_a)]) == 0
    assert main(["estimate", "madgwick", str(sparse_plain), "--output", str(out_b),
                 "--input-frame", "enu"]) == 0
    np.testing.assert_array_equal(_quats(_read(out_a)), _quats(_read(out_b)))


def test_a_suffix_contradicting_the_option_is_an_error(tmp_path: Path,
                                                       capsys: pytest.CaptureFixture[str]) -> None:
    src = tmp_path / "in.csv"
    lines = _write(tmp_path / "plain.csv", _dataset_a_rows()[:10]).read_text().splitlines()
    header = ",".join(h if h == "t_s" else f"{h}_android" for h in lines[0].split(","))
    src.write_text("\n".join([header, *lines[1:]]) + "\n")
    assert main(["estimate", "madgwick", str(src), "--output", str(tmp_path / "o.csv"),
                 "--input-frame", "enu"]) == 2
    err = capsys.readouterr().err
    assert "gx_rad_s_android" in err and "'android'" in err and "--input-frame enu" in err
