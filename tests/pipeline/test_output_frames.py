"""The frame of what a run hands out: the profile's ``output_frame`` for the CSV and console
sinks and for ``Pipeline.framed_events``; the Python helpers that convert at the edges.

Expected values are worked out by hand in each test (axis renames and sign flips)."""

from __future__ import annotations

import csv
import io
import math
import textwrap
from pathlib import Path

import numpy as np
import pytest
from tests.pipeline.test_pipeline import PROFILE

from imuhal.cli.main import main
from imuhal.core.errors import ProfileError
from imuhal.core.frames import quat_from_euler_deg, quat_to_matrix
from imuhal.core.samples import AccelSample, Frame, GyroSample, MagSample, Quantity
from imuhal.emulation import open_emulated
from imuhal.estimation.framed import (
    FramedAttitude,
    FramedSample,
    express,
    express_sample,
    sample_from_frame,
)
from imuhal.estimation.outputs import AttitudeEstimate, VerticalEstimate
from imuhal.plugins.manager import Registry
from imuhal.profile.loader import parse_profile
from imuhal.sinks.builtin import ConsoleSink, CsvSink, csv_columns

G = 9.80665
C15, S15 = math.cos(math.radians(15.0)), math.sin(math.radians(15.0))
NOSE_UP_30_HEADING_EAST = AttitudeEstimate(
    t_ns=1_000_000_000, source="ahrs",
    q_body_to_ned=tuple(float(v) for v in quat_from_euler_deg(0.0, 30.0, 90.0)),  # type: ignore[arg-type]
    linear_accel_ned_m_s2=(1.0, 2.0, 3.0))
LEVEL_ACCEL = AccelSample(t_ns=0, device="imu", frame=Frame.BODY_NED,
                          accel_m_s2=(0.0, 0.0, -G))


def _rows(path: Path) -> list[dict[str, str]]:
    with path.open() as f:
        return list(csv.DictReader(f))


def test_csv_sink_in_ros_frame_writes_enu_attitude_and_earth_axes(tmp_path: Path) -> None:
    """ENU earth, FLU body: q = (cos 15, 0, -sin 15, 0), ROS pitch -30 (nose down +), yaw 0
    (east); linear acceleration (north 1, east 2, down 3) is (east 2, north 1, up -3)."""
    sink = CsvSink(tmp_path / "log.csv", frame="ros")
    sink.handle(NOSE_UP_30_HEADING_EAST)
    sink.close()
    (row,) = _rows(tmp_path / "log.csv")
    got = [float(row[c]) for c in ("qw_enu", "qx_enu", "qy_enu", "qz_enu")]
    assert got == pytest.approx([C15, 0.0, -S15, 0.0], abs=1e-12)
    assert [float(row[c]) for c in ("roll_deg_enu", "pitch_deg_enu", "yaw_deg_enu")] == \
        pytest.approx([0.0, -30.0, 0.0], abs=1e-9)
    assert [float(row[c]) for c in ("lin_ae_m_s2", "lin_an_m_s2", "lin_au_m_s2")] == \
        pytest.approx([2.0, 1.0, -3.0])
    assert "qw" not in row and "lin_ad_m_s2" not in row


@pytest.mark.parametrize("frame, expected", [
    ("ned", (0.0, 0.0, -G)),       # specific force, z down
    ("enu", (0.0, 0.0, G)),        # specific force, z up
    ("android", (0.0, 0.0, G)),    # acceleration positive, z up
    ("win8", (0.0, 0.0, -G)),      # gravity positive, z up
    ("aerospace", (0.0, 0.0, G)),  # gravity positive, z down
])
def test_a_level_accelerometer_sample_is_logged_with_the_frames_axes_and_sign(
        tmp_path: Path, frame: str, expected: tuple[float, float, float]) -> None:
    sink = CsvSink(tmp_path / "log.csv", include_samples=True, frame=frame)
    sink.handle(LEVEL_ACCEL)
    sink.close()
    (row,) = _rows(tmp_path / "log.csv")
    suffix = "" if frame == "ned" else f"_{frame}"
    assert [float(row[f"a{c}_m_s2{suffix}"]) for c in "xyz"] == pytest.approx(expected)


def test_android_gyro_and_mag_columns_are_right_forward_up() -> None:
    gyro = GyroSample(t_ns=0, device="imu", frame=Frame.BODY_NED, gyro_rad_s=(0.1, 0.2, 0.3))
    mag = MagSample(t_ns=0, device="imu", frame=Frame.BODY_NED, mag_ut=(20.0, -5.0, 40.0))
    assert express_sample(gyro, "android").vector == pytest.approx((0.2, 0.1, -0.3))
    assert express_sample(mag, "android").columns() == pytest.approx(
        {"mx_ut_android": -5.0, "my_ut_android": 20.0, "mz_ut_android": -40.0})


def test_default_header_is_unchanged_ned() -> None:
    assert csv_columns("ned")[4:7] == ("ax_m_s2", "ay_m_s2", "az_m_s2")
    assert "lin_ad_m_s2" in csv_columns("ned") and "lin_au_m_s2" in csv_columns("win8")


def test_console_line_shows_the_frames_own_angles_and_names_it() -> None:
    out = io.StringIO()
    sink = ConsoleSink(out, frame="enu")
    sink.handle(NOSE_UP_30_HEADING_EAST)
    assert "pitch  -30.0" in out.getvalue() and "(enu)" in out.getvalue()


@pytest.mark.parametrize("frame", ["enu", "android", "win8", "aerospace"])
@pytest.mark.parametrize("channel", [Quantity.ACCEL, Quantity.GYRO, Quantity.MAG])
def test_a_reading_fed_from_another_frame_comes_back_unchanged(frame: str,
                                                               channel: Quantity) -> None:
    reading = (1.5, -2.0, 9.0)
    sample = sample_from_frame(channel, reading, frame, t_ns=5, device="phone")
    assert sample.frame is Frame.BODY_NED and sample.channel is channel
    assert express_sample(sample, frame).vector == reading


def test_a_level_phone_reading_becomes_ned_specific_force() -> None:
    """Android, flat on a table: (0, 0, +9.81) (acceleration positive, z up)."""
    sample = sample_from_frame(Quantity.ACCEL, (0.0, 0.0, G), "android", t_ns=0, device="phone")
    assert sample.vector == pytest.approx((0.0, 0.0, -G))


def test_profile_output_frame_accepts_aliases_and_rejects_unknown_names(
        registry: Registry) -> None:
    profile = parse_profile(PROFILE + "output_frame: ROS\n", "t.yaml", registry)
    assert profile.output_frame == "enu"
    assert parse_profile(PROFILE, "t.yaml", registry).output_frame == "ned"
    with pytest.raises(ProfileError, match=r"output_frame.*'nwu'.*enu"):
        parse_profile(PROFILE + "output_frame: nwu\n", "t.yaml", registry)


def test_framed_events_follow_the_profiles_output_frame(registry: Registry) -> None:
    profile = parse_profile(textwrap.dedent(PROFILE) + "output_frame: android\n", "t.yaml",
                            registry)
    with open_emulated(profile, registry, scenario="thermal") as p:
        events = list(p.framed_events(0.2))
    accel = [e for e in events if isinstance(e, FramedSample)]
    assert accel and all(e.frame.name == "android" for e in accel)
    # the thermal scenario starts level and still: Android reads +g on z (up)
    assert accel[0].vector == pytest.approx((0.0, 0.0, G), abs=0.01)
    assert any(isinstance(e, VerticalEstimate) for e in events)  # no frame: unchanged


def test_express_converts_attitudes_and_leaves_frameless_events_alone() -> None:
    framed = express(NOSE_UP_30_HEADING_EAST, "win8")
    assert isinstance(framed, FramedAttitude)
    # Windows 8: sensor right-forward-up into ENU; yaw anticlockwise from north: east = 270
    assert framed.euler_deg.yaw == pytest.approx(270.0)
    assert np.linalg.norm(framed.q_body_to_earth) == pytest.approx(1.0)
    vertical = VerticalEstimate(t_ns=0, source="vario", altitude_m=1.0, climb_m_s=0.5)
    assert express(vertical, "win8") is vertical


def test_a_chip_frame_sample_keeps_its_row_but_no_vector_in_another_frame(tmp_path: Path) -> None:
    sink = CsvSink(tmp_path / "log.csv", include_samples=True, frame="enu")
    sink.handle(AccelSample(t_ns=0, device="imu", frame=Frame.SENSOR, accel_m_s2=(1.0, 2.0, 3.0)))
    sink.close()
    (row,) = _rows(tmp_path / "log.csv")
    assert row["kind"] == "accel" and row["ax_m_s2_enu"] == ""


def test_run_output_frame_option_overrides_the_profile_and_renames_the_columns(
        tmp_path: Path) -> None:
    """The same seeded emulated run logged in ned and in ros: the same attitudes, the ros log's
    quaternions re-expressed by hand (R_enu = E R_ned B^T, E and B the axis renames)."""
    logs = {}
    for frame in ("ned", "ros"):
        out = tmp_path / f"{frame}.csv"
        # --skip-calibration: both runs fly the same uncalibrated board; the calibration an
        # emulated run makes first (seconds of CPU, tested in tests/calibration) is not compared
        assert main(["run", "--skip-calibration", "--duration", "1", "--output", str(out),
                     "--quiet", "--output-frame", frame]) == 0
        logs[frame] = [r for r in _rows(out) if r["kind"] == "attitude"]
    assert logs["ned"] and len(logs["ned"]) == len(logs["ros"])
    enu_from_ned = np.array([[0.0, 1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, -1.0]])
    flu_from_frd = np.diag([1.0, -1.0, -1.0])
    for ned, ros in zip(logs["ned"][::10], logs["ros"][::10], strict=True):
        q_ned = [float(ned[c]) for c in ("qw", "qx", "qy", "qz")]
        q_ros = [float(ros[c]) for c in ("qw_enu", "qx_enu", "qy_enu", "qz_enu")]
        np.testing.assert_allclose(quat_to_matrix(q_ros),
                                   enu_from_ned @ quat_to_matrix(q_ned) @ flu_from_frd.T,
                                   atol=1e-12)
