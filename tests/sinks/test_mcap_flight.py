"""`imuhal run --mcap`: a seed-gps-vario flight written as ROS 2 messages in MCAP, read back
with rosbags (an independent reader and CDR decoder, with its own ROS 2 Humble message types):
every message of the CSV log, stamps in order, the orientation of the CSV log after the frame
conversion, ENU/FLU checked against the simulation's truth, and a run killed by SIGKILL.

60 s here; `pytest -m long tests/sinks/test_mcap_flight.py` flies 600 s through the same checks.
"""

from __future__ import annotations

import csv
import math
import os
import signal
import subprocess
import sys
import time
from collections import Counter
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest

from imuhal.cli.main import main
from imuhal.core.conventions import ENU, NED, convert_quat
from imuhal.profile.bundled import bundled_profiles
from imuhal.sim.truth_csv import read_truth_csv

pytest.importorskip("mcap_ros2", reason="the ros extra (mcap, mcap-ros2-support) is missing")
pytest.importorskip("pynmea2", reason="the gps extra (pynmea2, pyubx2) is not installed")
rosbags_highlevel = pytest.importorskip("rosbags.highlevel", reason="rosbags is not installed")
from rosbags.typesys import Stores, get_typestore  # noqa: E402

pytestmark = pytest.mark.slow

GPS_VARIO = str(bundled_profiles()["seed-gps-vario.yaml"])
TYPESTORE = get_typestore(Stores.ROS2_HUMBLE)


@dataclass
class Flight:
    """One flight's outputs: the MCAP's messages per topic (stamp ns, decoded message), the
    CSV log's rows and the truth columns."""

    topics: dict[str, list[tuple[int, object]]]
    types: dict[str, str]
    rows: list[dict[str, str]]
    truth: dict[str, np.ndarray]


def read_mcap(path: Path) -> tuple[dict[str, list[tuple[int, object]]], dict[str, str]]:
    topics: dict[str, list[tuple[int, object]]] = {}
    types: dict[str, str] = {}
    with rosbags_highlevel.AnyReader([path], default_typestore=TYPESTORE) as reader:
        for conn, _log_ns, raw in reader.messages():
            # decoded with rosbags' own Humble definitions, not the file's schemas
            msg = TYPESTORE.deserialize_cdr(raw, conn.msgtype)
            st = msg.header.stamp
            topics.setdefault(conn.topic, []).append((st.sec * 1_000_000_000 + st.nanosec, msg))
            types[conn.topic] = conn.msgtype
    return topics, types


def fly(tmp: Path, duration_s: int) -> Flight:
    log, truth, bag = tmp / "flight.csv", tmp / "truth.csv", tmp / "flight.mcap"
    assert main(["run", GPS_VARIO, "--emulate", "thermal", "--duration", str(duration_s),
                 "--quiet", "--samples", "--output", str(log), "--truth", str(truth),
                 "--mcap", str(bag)]) == 0
    assert not (tmp / "flight.mcap.partial").exists()
    topics, types = read_mcap(bag)
    with log.open(newline="") as f:
        rows = list(csv.DictReader(f))
    return Flight(topics, types, rows, read_truth_csv(truth)[0])


@pytest.fixture(scope="module")
def flight(tmp_path_factory: pytest.TempPathFactory) -> Flight:
    return fly(tmp_path_factory.mktemp("mcap"), 60)


def _us(t_ns: int) -> int:
    return round(t_ns / 1000)


def _row_us(row: dict[str, str]) -> int:
    return round(float(row["t_s"]) * 1e6)


def check_every_message(f: Flight) -> None:
    valid = [r for r in f.rows if r["flags"] == "0"]
    by_kind = Counter((r["kind"], r["source"]) for r in valid)
    imu_epochs = {(r["source"], r["t_s"]) for r in valid if r["kind"] in ("accel", "gyro")}
    expected = {
        "imu/data_raw": len(imu_epochs),
        "imu/data": by_kind["attitude", "ahrs"],
        "imu/mag": by_kind["mag", "mag"],
        "pressure": by_kind["pressure", "baro"],
        "baro/temperature": by_kind["temperature", "baro"],
        "imu/temperature": by_kind["temperature", "imu"],
        "gps/fix": by_kind["position", "gps"],
        "gps/vel": by_kind["velocity", "gps"],
    }
    assert {t: len(m) for t, m in f.topics.items()} == expected
    assert min(expected.values()) > 0
    assert f.types["imu/data"] == f.types["imu/data_raw"] == "sensor_msgs/msg/Imu"
    assert f.types["gps/fix"] == "sensor_msgs/msg/NavSatFix"
    # the stamps are the CSV rows' times, to the CSV's microsecond: the CSV formats the
    # stamp's float seconds to 6 decimals, which can round a stamp ending in 500 ns the other
    # way (stamps on the chip's own clock fall anywhere between whole microseconds)
    for topic, kind in (("imu/data", "attitude"), ("gps/fix", "position")):
        row_us = np.array([_row_us(r) for r in valid if r["kind"] == kind])
        stamp_us = np.array([_us(t) for t, _ in f.topics[topic]])
        assert len(stamp_us) == len(row_us)
        assert np.max(np.abs(stamp_us - row_us)) <= 1, topic


def check_stamps_in_order(f: Flight) -> None:
    for topic, msgs in f.topics.items():
        stamps = np.array([t for t, _ in msgs])
        assert np.all(np.diff(stamps) > 0), topic
        assert all(m.header.frame_id == "seed-gps-vario" for _, m in msgs), topic


def _angle_deg(q1: np.ndarray, q2: np.ndarray) -> np.ndarray:
    dots = np.abs(np.sum(q1 * q2, axis=1)) / (np.linalg.norm(q1, axis=1)
                                               * np.linalg.norm(q2, axis=1))
    return np.degrees(2 * np.arccos(np.clip(dots, -1.0, 1.0)))


def check_orientation_matches_the_csv(f: Flight) -> None:
    csv_q = np.array([[float(r[c]) for c in ("qw", "qx", "qy", "qz")] for r in f.rows
                      if r["kind"] == "attitude"])
    ros_q = np.array([[m.orientation.w, m.orientation.x, m.orientation.y, m.orientation.z]
                      for _, m in f.topics["imu/data"]])
    assert _angle_deg(ros_q, convert_quat(csv_q, NED, ENU)).max() < 0.01


def _truth_at(f: Flight, stamps_ns: list[int], names: tuple[str, ...]) -> np.ndarray:
    # truth rows are at the times of the log's rows, in the log's order (not sorted: a
    # GNSS epoch is logged after later IMU samples); each stamp must have one
    row_of = {int(t): i for i, t in enumerate(np.round(f.truth["t_s"] * 1e6))}
    idx = np.array([row_of[_us(t)] for t in stamps_ns])
    return np.stack([f.truth[n][idx] for n in names], axis=1)


def check_enu_flu_against_the_truth(f: Flight) -> None:
    # Written from REP-103 directly: NED (n, e, d) is ENU (e, n, -d); FRD (x, y, z) is
    # FLU (x, -y, -z). The forward axis of the board in the earth frame, from the truth and
    # from the ROS orientation, must agree up to the estimator's error.
    msgs = f.topics["imu/data"]
    q_true = _truth_at(f, [t for t, _ in msgs], ("qw", "qx", "qy", "qz"))
    heading_true = np.degrees(np.arctan2(
        2 * (q_true[:, 0] * q_true[:, 3] + q_true[:, 1] * q_true[:, 2]),
        1 - 2 * (q_true[:, 2] ** 2 + q_true[:, 3] ** 2)))  # clockwise from north
    yaw_enu = np.array([math.degrees(math.atan2(
        2 * (m.orientation.w * m.orientation.z + m.orientation.x * m.orientation.y),
        1 - 2 * (m.orientation.y ** 2 + m.orientation.z ** 2))) for _, m in msgs])
    # heading north (0) is ENU yaw +90 (anticlockwise from east)
    err = (yaw_enu - (90.0 - heading_true) + 180.0) % 360.0 - 180.0
    # What remains is the estimator's own heading error (up to ~15 deg in this thermal, the
    # same in the CSV log's NED yaw); a wrong axis or sign would be 180 deg off, or swing
    # with the heading as the glider circles.
    assert np.abs(err[len(err) // 10:]).max() < 20.0
    heading_csv = np.array([float(r["yaw_deg"]) for r in f.rows if r["kind"] == "attitude"])
    err_csv = (heading_true - heading_csv + 180.0) % 360.0 - 180.0
    assert np.abs(err - err_csv).max() < 0.01
    # gravity on +z of the FLU specific force, each axis as the truth's
    raw = f.topics["imu/data_raw"]
    f_true = _truth_at(f, [t for t, _ in raw], ("fx_m_s2", "fy_m_s2", "fz_m_s2"))
    f_flu = np.array([[m.linear_acceleration.x, m.linear_acceleration.y,
                       m.linear_acceleration.z] for _, m in raw])
    assert f_flu[:, 2].mean() > 9.0
    diff = f_flu - f_true * np.array([1.0, -1.0, -1.0])
    # what is left is the emulated sensor's bias (about 0.5 m/s^2 on x in this flight) and
    # noise; a flipped z would be 2 g off
    assert np.abs(diff.mean(axis=0)) == pytest.approx([0.0, 0.0, 0.0], abs=0.8)
    assert abs(diff[:, 2].mean()) < 0.3


def test_every_message_of_the_csv_log_is_in_the_mcap(flight: Flight) -> None:
    check_every_message(flight)


def test_stamps_are_in_order_and_every_message_names_the_board_frame(flight: Flight) -> None:
    check_stamps_in_order(flight)


def test_the_orientation_is_the_csv_logs_converted_to_enu_within_0_01_deg(
        flight: Flight) -> None:
    check_orientation_matches_the_csv(flight)


def test_enu_orientation_and_flu_acceleration_agree_with_the_simulated_truth(
        flight: Flight) -> None:
    check_enu_flu_against_the_truth(flight)


@pytest.mark.long
def test_a_600_s_flight_passes_every_check(tmp_path: Path) -> None:
    f = fly(tmp_path, 600)
    check_every_message(f)
    check_stamps_in_order(f)
    check_orientation_matches_the_csv(f)
    check_enu_flu_against_the_truth(f)


def test_a_run_killed_by_sigkill_leaves_a_partial_mcap_readable_up_to_its_last_second(
        tmp_path: Path, flight: Flight) -> None:
    bag = tmp_path / "killed.mcap"
    # Not quiet: with stdout a pipe, the console prints the run's time every second, a lower
    # bound of how far the run had come when it was killed.
    proc = subprocess.Popen(
        [sys.executable, "-m", "imuhal.cli.main", "run", GPS_VARIO, "--emulate", "thermal",
         "--duration", "60", "--mcap", str(bag)],
        stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True)
    try:
        assert proc.stdout is not None
        seen_s = 0.0
        deadline = time.monotonic() + 120
        while seen_s < 6.0 and time.monotonic() < deadline:
            line = proc.stdout.readline()
            if line.startswith("t="):
                seen_s = float(line[2:].split("s")[0])
        os.kill(proc.pid, signal.SIGKILL)
    finally:
        proc.kill()
        proc.wait()
    assert seen_s >= 6.0
    assert not bag.exists()  # never committed under the final name
    # what a user does with it: give it its name back (readers choose the format by suffix)
    recovered = (tmp_path / "killed.mcap.partial").rename(tmp_path / "recovered.mcap")
    topics, _ = read_mcap(recovered)
    raw = [t for t, _ in topics["imu/data_raw"]]
    assert raw[-1] / 1e9 >= seen_s - 1.0 - 0.01
    # what is there is the same flight, message for message, from its start
    full = flight.topics["imu/data"]
    got = topics["imu/data"]
    assert [t for t, _ in got] == [t for t, _ in full[:len(got)]]
    assert all(a.orientation.w == b.orientation.w for (_, a), (_, b) in
               zip(got, full[:len(got)], strict=True))
