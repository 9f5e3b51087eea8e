"""A real ground station on imuhal's MAVLink stream: MAVProxy, headless, listening on a local
UDP port while an emulated flight is sent to it in real time. MAVProxy must take the board as
its vehicle (the profile's system and component ids) and log every message the run sent, with
the run's values: its telemetry log is read back and compared with the run's CSV log."""

from __future__ import annotations

import csv
import re
import shutil
import signal
import socket
import subprocess
import sys
import threading
import time
from pathlib import Path
from typing import Any

import pytest

from imuhal.cli.main import main
from imuhal.profile.bundled import bundled_profiles

pytest.importorskip("pymavlink", reason="the mavlink extra (pymavlink) is not installed")
pytest.importorskip("pynmea2", reason="the gps extra (pynmea2, pyubx2) is not installed")
MAVPROXY = shutil.which("mavproxy.py", path=str(Path(sys.executable).parent))
if MAVPROXY is None:
    pytest.skip("MAVProxy not installed (pip install -e \".[test]\")", allow_module_level=True)
from pymavlink import mavutil  # noqa: E402  (after the skips: an optional extra)

GPS_VARIO = str(bundled_profiles()["seed-gps-vario.yaml"])
TYPES = ("HEARTBEAT", "HIGHRES_IMU", "SCALED_PRESSURE", "ATTITUDE_QUATERNION",
         "GLOBAL_POSITION_INT")


class MavProxy:
    """``mavproxy.py --daemon --non-interactive`` on ``udpin:127.0.0.1:PORT``, its output read
    by a thread, its telemetry log in ``folder``."""

    def __init__(self, folder: Path) -> None:
        probe = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        probe.bind(("127.0.0.1", 0))
        self.port = probe.getsockname()[1]
        probe.close()
        self.tlog = folder / "flight.tlog"
        assert MAVPROXY is not None
        self.process = subprocess.Popen(
            [sys.executable, MAVPROXY, f"--master=udpin:127.0.0.1:{self.port}", "--daemon",
             "--non-interactive", f"--logfile={self.tlog}", f"--state-basedir={folder}",
             "--default-modules="],  # no modules: no terminal, map or console
            cwd=folder, stdin=subprocess.DEVNULL, stdout=subprocess.PIPE,
            stderr=subprocess.STDOUT, text=True)
        self.lines: list[str] = []
        self._reader = threading.Thread(target=self._read, daemon=True)
        self._reader.start()

    def _read(self) -> None:
        assert self.process.stdout is not None
        for line in self.process.stdout:
            self.lines.append(line.rstrip())

    def wait_for(self, text: str, timeout_s: float) -> None:
        deadline = time.monotonic() + timeout_s
        while not any(text in line for line in self.lines):
            if time.monotonic() > deadline or self.process.poll() is not None:
                raise AssertionError(f"MAVProxy never said {text!r}:\n" + "\n".join(self.lines))
            time.sleep(0.05)

    def stop(self) -> None:
        if self.process.poll() is None:
            self.process.send_signal(signal.SIGINT)
            try:
                self.process.wait(timeout=20)
            except subprocess.TimeoutExpired:
                self.process.kill()
                self.process.wait()
        self._reader.join(timeout=5)


def _wait_until_settled(path: Path, quiet_s: float, timeout_s: float) -> None:
    """Return once ``path`` has not grown for ``quiet_s`` (or after ``timeout_s``)."""
    deadline = time.monotonic() + timeout_s
    size, since = -1, time.monotonic()
    while time.monotonic() < deadline:
        now_size = path.stat().st_size if path.exists() else 0
        if now_size != size:
            size, since = now_size, time.monotonic()
        elif time.monotonic() - since >= quiet_s:
            return
        time.sleep(0.1)


def _logged(tlog: Path) -> dict[str, list[Any]]:
    """The messages of system 1 in MAVProxy's telemetry log, by type (MAVProxy's own requests
    to the vehicle, from system 255, are in it too)."""
    log = mavutil.mavlink_connection(str(tlog), dialect="common")
    out: dict[str, list[Any]] = {}
    while (m := log.recv_match()) is not None:
        if m.get_srcSystem() == 1:
            out.setdefault(m.get_type(), []).append(m)
    return out


def _sent_counts(stderr: str) -> dict[str, int]:
    """The run's own count of what it sent (its summary line ``mavlink: sent N TYPE, ...``)."""
    line = next(x for x in stderr.splitlines() if x.startswith("mavlink: sent "))
    return {name: int(n) for n, name in re.findall(r"(\d+) ([A-Z_]+)", line)}


@pytest.mark.slow
def test_mavproxy_takes_the_board_as_its_vehicle_and_logs_every_message_with_its_values(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    gcs = MavProxy(tmp_path)
    try:
        gcs.wait_for("Waiting for heartbeat", timeout_s=60)
        csv_log = tmp_path / "log.csv"
        # --skip-calibration: every check is against this run's own log, not the calibration
        # an emulated run makes first (seconds of CPU; tests/calibration)
        assert main(["run", GPS_VARIO, "--emulate", "thermal", "--skip-calibration",
                     "--duration", "6", "--realtime", "--quiet", "--samples", "--output",
                     str(csv_log),
                     "--mavlink", f"udpout:127.0.0.1:{gcs.port}"]) == 0
        gcs.wait_for("online system 1", timeout_s=30)
        # the last datagrams into its log: MAVProxy is another process, which a loaded
        # machine (the suite's other worker) can keep from its socket for longer than a
        # fixed second (a fresh-clone CI logged 249 of 275 HIGHRES_IMU after 1 s)
        _wait_until_settled(gcs.tlog, quiet_s=2.0, timeout_s=30.0)
    finally:
        gcs.stop()
    assert any("Detected vehicle 1:1" in line for line in gcs.lines), gcs.lines
    logged = _logged(gcs.tlog)
    sent = _sent_counts(capsys.readouterr().err)
    assert set(sent) == set(TYPES)
    # loopback at the run's pace: MAVProxy received and logged every message sent
    imu_us = [m.time_usec for m in logged.get("HIGHRES_IMU", [])]
    assert {t: len(logged.get(t, [])) for t in TYPES} == sent, (
        "HIGHRES_IMU logged from "
        f"{imu_us[0] if imu_us else None} to {imu_us[-1] if imu_us else None} us")
    with csv_log.open(newline="") as f:
        rows = [r for r in csv.DictReader(f) if r["flags"] == "0"]
    at_us = {(r["kind"], round(float(r["t_s"]) * 1e6)): r for r in rows}
    for m in logged["HIGHRES_IMU"][::10]:
        # time_usec truncates the stamp to the microsecond, the log's t_s rounds it
        t_us = m.time_usec if ("gyro", m.time_usec) in at_us else m.time_usec + 1
        g, a = at_us["gyro", t_us], at_us["accel", t_us]
        assert (m.xgyro, m.ygyro, m.zgyro) == pytest.approx(
            tuple(float(g[k]) for k in ("gx_rad_s", "gy_rad_s", "gz_rad_s")), rel=1e-6,
            abs=1e-9)
        assert (m.xacc, m.yacc, m.zacc) == pytest.approx(
            tuple(float(a[k]) for k in ("ax_m_s2", "ay_m_s2", "az_m_s2")), rel=1e-6)
    attitude_ms = {round(float(r["t_s"]) * 1e6) // 1000: r for r in rows
                   if r["kind"] == "attitude"}
    for m in logged["ATTITUDE_QUATERNION"][::10]:
        r = attitude_ms[m.time_boot_ms]
        assert (m.q1, m.q2, m.q3, m.q4) == pytest.approx(
            tuple(float(r[k]) for k in ("qw", "qx", "qy", "qz")), abs=1e-7)
    fixes = [r for r in rows if r["kind"] == "position"]
    assert [(m.lat, m.lon) for m in logged["GLOBAL_POSITION_INT"]] == [
        (round(float(r["latitude_deg"]) * 1e7), round(float(r["longitude_deg"]) * 1e7))
        for r in fixes]
    baro_ms = {round(float(r["t_s"]) * 1e6) // 1000: r for r in rows
               if r["kind"] == "pressure" and r["source"] == "baro"}
    for m in logged["SCALED_PRESSURE"]:
        assert m.press_abs == pytest.approx(float(baro_ms[m.time_boot_ms]["pressure_pa"]) / 100,
                                            rel=1e-6)
