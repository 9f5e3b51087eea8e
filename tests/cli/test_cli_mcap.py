"""`--mcap` on `imuhal replay` and `imuhal estimate`, and its user mistakes (one line, exit 2).
The messages themselves are checked in tests/sinks/test_mcap_flight.py."""

from __future__ import annotations

import csv
from pathlib import Path

import pytest

from imuhal.cli.main import main
from imuhal.profile.bundled import bundled_profiles

pytest.importorskip("mcap_ros2", reason="the ros extra (mcap, mcap-ros2-support) is missing")
rosbags_highlevel = pytest.importorskip("rosbags.highlevel", reason="rosbags is not installed")

VARIO = str(bundled_profiles()["seed-paraglider-vario.yaml"])


def _messages(path: Path) -> dict[str, list[bytes]]:
    out: dict[str, list[bytes]] = {}
    with rosbags_highlevel.AnyReader([path]) as reader:
        for conn, _t, raw in reader.messages():
            out.setdefault(conn.topic, []).append(bytes(raw))
    return out


def test_replay_writes_the_same_messages_as_the_recorded_run(tmp_path: Path) -> None:
    rec, live, again = tmp_path / "run.imurec", tmp_path / "live.mcap", tmp_path / "again.mcap"
    # --skip-calibration here and below: the calibration an emulated run makes first (seconds
    # of CPU, tested in tests/calibration) is not what these compare
    assert main(["run", VARIO, "--emulate", "thermal", "--skip-calibration", "--duration", "3",
                 "--quiet", "--record", str(rec), "--mcap", str(live)]) == 0
    assert main(["replay", str(rec), "--quiet", "--mcap", str(again)]) == 0
    live_msgs, again_msgs = _messages(live), _messages(again)
    assert {"imu/data_raw", "imu/data", "imu/mag", "pressure"} <= set(live_msgs)
    assert again_msgs == live_msgs  # byte for byte: the same floats, stamps and frame id


def test_estimate_writes_its_estimates_and_the_logs_samples(tmp_path: Path,
                                                            capsys: pytest.CaptureFixture[str]
                                                            ) -> None:
    log, att, bag = tmp_path / "log.csv", tmp_path / "att.csv", tmp_path / "att.mcap"
    assert main(["run", VARIO, "--emulate", "thermal", "--skip-calibration", "--duration", "3",
                 "--quiet", "--samples", "--output", str(log)]) == 0
    assert main(["estimate", "mahony", str(log), "-o", str(att), "--mcap", str(bag),
                 "--frame-id", "imu_link"]) == 0
    assert "ROS 2 messages to" in capsys.readouterr().err
    with att.open(newline="") as f:
        estimates = sum(1 for _ in csv.DictReader(f))
    msgs = _messages(bag)
    assert len(msgs["imu/data"]) == estimates > 0
    assert len(msgs["imu/data_raw"]) > 0
    with rosbags_highlevel.AnyReader([bag]) as reader:
        conn = next(c for c in reader.connections if c.topic == "imu/data")
        _c, _t, raw = next(reader.messages([conn]))
        assert reader.deserialize(raw, conn.msgtype).header.frame_id == "imu_link"


def test_mcap_over_the_profile_is_refused(tmp_path: Path,
                                          capsys: pytest.CaptureFixture[str]) -> None:
    profile = tmp_path / "board.yaml"
    profile.write_text(Path(VARIO).read_text())
    assert main(["run", str(profile), "--emulate", "thermal", "--duration", "1", "--quiet",
                 "--mcap", str(profile)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--mcap" in err[0] and "PROFILE" in err[0]


def test_estimate_mcap_needs_a_run_log(tmp_path: Path,
                                       capsys: pytest.CaptureFixture[str]) -> None:
    wide = tmp_path / "wide.csv"
    wide.write_text("t_s,gx_rad_s,gy_rad_s,gz_rad_s,ax_m_s2,ay_m_s2,az_m_s2\n"
                    "0.0,0,0,0,0,0,-9.81\n0.01,0,0,0,0,0,-9.81\n")
    assert main(["estimate", "madgwick", str(wide), "-o", str(tmp_path / "o.csv"),
                 "--mcap", str(tmp_path / "o.mcap")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "needs a run log" in err[0]
    assert not (tmp_path / "o.mcap").exists() and not (tmp_path / "o.csv").exists()
