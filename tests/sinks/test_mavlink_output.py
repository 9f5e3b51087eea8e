"""`imuhal run --mavlink udpout:HOST:PORT`: every message type decoded from a local UDP socket
with values matching the run's CSV log, and a ground-station client in its own process
(pymavlink's mavutil, as MAVProxy uses it) that connects and sees the board."""

from __future__ import annotations

import csv
import json
import math
import socket
import subprocess
import sys
import threading
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from imuhal.cli.main import main
from imuhal.core.errors import ImuhalError
from imuhal.profile.bundled import bundled_profiles

pytest.importorskip("pymavlink", reason="the mavlink extra (pymavlink) is not installed")
pytest.importorskip("pynmea2", reason="the gps extra (pynmea2, pyubx2) is not installed")
from pymavlink.dialects.v20 import common as mavlink2

from imuhal.sinks.mavlink.sink import MavlinkSink, parse_udpout

GPS_VARIO = str(bundled_profiles()["seed-gps-vario.yaml"])
DURATION_S = 10


RECEIVE_BUFFER_BYTES = 4 << 20
"""The receiving socket's buffer: the whole run's datagrams (about 1,100 in 10 s, each
charged about 1 KiB in the kernel), so none is dropped while the draining thread waits for
the GIL behind the emulated run in the same process (the default 208 KiB held about 200:
a CI run once received 377 of 500 HIGHRES_IMU). Linux caps it at net.core.rmem_max."""


class Receiver:
    """A UDP socket on loopback, drained by a thread (the run sends faster than the
    default socket buffer holds), decoding every datagram with pymavlink's parser."""

    def __init__(self) -> None:
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, RECEIVE_BUFFER_BYTES)
        self.sock.bind(("127.0.0.1", 0))
        self.sock.settimeout(0.2)
        self.port = self.sock.getsockname()[1]
        self.messages: list[Any] = []
        self._parser = mavlink2.MAVLink(None)
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._drain, daemon=True)
        self._thread.start()

    def _drain(self) -> None:
        while not self._stop.is_set():
            try:
                data = self.sock.recv(65536)
            except TimeoutError:
                continue
            self.messages.extend(self._parser.parse_buffer(data) or [])

    def stop(self) -> None:
        self._stop.set()
        self._thread.join()
        self.sock.close()

    def of(self, name: str) -> list[Any]:
        return [m for m in self.messages if m.get_type() == name]


@pytest.fixture(scope="module")
def sent(tmp_path_factory: pytest.TempPathFactory) -> Iterator[tuple[Receiver, list[dict]]]:
    log = tmp_path_factory.mktemp("mavlink") / "log.csv"
    rx = Receiver()
    try:
        assert main(["run", GPS_VARIO, "--emulate", "thermal", "--duration", str(DURATION_S),
                     "--quiet", "--samples", "--output", str(log),
                     "--mavlink", f"udpout:127.0.0.1:{rx.port}"]) == 0
    finally:
        rx.stop()
    with log.open(newline="") as f:
        rows = [r for r in csv.DictReader(f) if r["flags"] == "0"]
    yield rx, rows


def _at_us(rows: list[dict], kind: str) -> dict[int, dict]:
    return {round(float(r["t_s"]) * 1e6): r for r in rows if r["kind"] == kind}


def _latest_before(rows: list[dict], kind: str, t_us: int) -> dict:
    return [r for r in rows if r["kind"] == kind and round(float(r["t_s"]) * 1e6) <= t_us][-1]


def _f(row: dict, name: str) -> float:
    return float(row[name])


def _latest_seen_before(rows: list[dict], kind: str, row: dict) -> dict:
    """The latest ``kind`` row the log received before ``row``: the sink sees events in the
    order the log does, and a magnetometer field stamped at its measurement (the AK8963's
    copies through the MPU's master) can arrive after an IMU sample with a later stamp."""
    i = next(i for i, r in enumerate(rows) if r is row)
    return [r for r in rows[:i] if r["kind"] == kind][-1]


def _ms(row: dict) -> int:
    """time_boot_ms of a log row: whole milliseconds of its time (the log has microseconds)."""
    return round(float(row["t_s"]) * 1e6) // 1000


def test_a_heartbeat_a_second_from_the_profiles_ids(sent: tuple[Receiver, list]) -> None:
    rx, _ = sent
    beats = rx.of("HEARTBEAT")
    assert DURATION_S - 1 <= len(beats) <= DURATION_S + 1
    assert {(b.get_srcSystem(), b.get_srcComponent()) for b in beats} == {(1, 1)}
    assert all(b.system_status == 4 and b.autopilot == 0 for b in beats)


def test_highres_imu_is_the_logs_body_frd_sample_in_mavlink_units_at_50_hz(
        sent: tuple[Receiver, list]) -> None:
    rx, rows = sent
    imus = rx.of("HIGHRES_IMU")
    assert abs(len(imus) - 50 * DURATION_S) <= 50  # start-up takes its part of the 10 s
    gyro_at = _at_us(rows, "gyro")
    accel_at = _at_us(rows, "accel")
    for m in imus[5::25]:
        # time_usec truncates the stamp to the microsecond, the log's t_s rounds it
        t_us = m.time_usec if m.time_usec in gyro_at else m.time_usec + 1
        g, a = gyro_at[t_us], accel_at[t_us]
        assert (m.xgyro, m.ygyro, m.zgyro) == pytest.approx(
            (_f(g, "gx_rad_s"), _f(g, "gy_rad_s"), _f(g, "gz_rad_s")), rel=1e-6, abs=1e-9)
        assert (m.xacc, m.yacc, m.zacc) == pytest.approx(
            (_f(a, "ax_m_s2"), _f(a, "ay_m_s2"), _f(a, "az_m_s2")), rel=1e-6)
        assert m.zacc < -8.0  # specific force, body z down: gravity reads negative
        mag = _latest_seen_before(rows, "mag", g)
        assert (m.xmag, m.ymag, m.zmag) == pytest.approx(
            (_f(mag, "mx_ut") / 100, _f(mag, "my_ut") / 100, _f(mag, "mz_ut") / 100),
            rel=1e-6)  # gauss
        p = _latest_before(rows, "pressure", m.time_usec)
        assert m.abs_pressure == pytest.approx(_f(p, "pressure_pa") / 100, rel=1e-6)  # hPa
        assert m.fields_updated & 0b111111 == 0b111111  # accel and gyro are new every time


def test_attitude_quaternion_is_the_logs_body_to_ned_attitude(
        sent: tuple[Receiver, list]) -> None:
    rx, rows = sent
    atts = rx.of("ATTITUDE_QUATERNION")
    assert abs(len(atts) - 50 * DURATION_S) <= 50
    by_ms = {_ms(r): r for r in rows if r["kind"] == "attitude"}
    for m in atts[::20]:
        r = by_ms[m.time_boot_ms]
        assert (m.q1, m.q2, m.q3, m.q4) == pytest.approx(
            (_f(r, "qw"), _f(r, "qx"), _f(r, "qy"), _f(r, "qz")), abs=1e-7)


def test_scaled_pressure_is_in_hpa_and_centidegrees(sent: tuple[Receiver, list]) -> None:
    rx, rows = sent
    msgs = rx.of("SCALED_PRESSURE")
    assert abs(len(msgs) - 10 * DURATION_S) <= 10
    by_ms = {_ms(r): r for r in rows if r["kind"] == "pressure" and r["source"] == "baro"}
    for m in msgs[1::10]:
        assert m.press_abs == pytest.approx(_f(by_ms[m.time_boot_ms], "pressure_pa") / 100,
                                            rel=1e-6)
        # the barometer's temperature as last read: the one of this conversion comes after
        # its pressure
        t = _latest_before([r for r in rows if r["source"] == "baro"], "temperature",
                           m.time_boot_ms * 1000 - 1)
        assert m.temperature == round(_f(t, "temperature_degc") * 100)


def test_global_position_int_is_every_gnss_fix_in_mavlink_units(
        sent: tuple[Receiver, list]) -> None:
    rx, rows = sent
    msgs = rx.of("GLOBAL_POSITION_INT")
    fixes = [r for r in rows if r["kind"] == "position"]
    assert len(msgs) == len(fixes) > 0
    home_mm = round(_f(fixes[0], "height_msl_m") * 1000)
    for m, fix in zip(msgs, fixes, strict=True):
        assert m.time_boot_ms == _ms(fix)
        assert m.lat == round(_f(fix, "latitude_deg") * 1e7)
        assert m.lon == round(_f(fix, "longitude_deg") * 1e7)
        assert m.alt == round(_f(fix, "height_msl_m") * 1000)
        assert abs(m.relative_alt - (m.alt - home_mm)) <= 1
        assert 0 <= m.hdg < 36000
    vel = _latest_before(rows, "velocity", round(_f(fixes[-1], "t_s") * 1e6))
    assert msgs[-1].vx == round(_f(vel, "vn_m_s") * 100)
    assert msgs[-1].vz == round(_f(vel, "vd_m_s") * 100)


GROUND_STATION = """
import json, sys
from pymavlink import mavutil
gcs = mavutil.mavlink_connection(sys.argv[1], source_system=255, dialect="common")
print("listening", flush=True)
seen = {}
wanted = {"HEARTBEAT", "HIGHRES_IMU", "SCALED_PRESSURE", "ATTITUDE_QUATERNION",
          "GLOBAL_POSITION_INT"}
while set(seen) < wanted:
    m = gcs.recv_match(blocking=True, timeout=30)
    if m is None:
        break
    seen.setdefault(m.get_type(), (m.get_srcSystem(), m.get_srcComponent()))
print(json.dumps({"seen": seen, "target": [gcs.target_system, gcs.target_component],
                  "mavlink20": bool(gcs.WIRE_PROTOCOL_VERSION == "2.0")}), flush=True)
"""


def test_a_ground_station_in_another_process_connects_and_sees_every_message(
        tmp_path: Path) -> None:
    probe = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    probe.bind(("127.0.0.1", 0))
    port = probe.getsockname()[1]
    probe.close()
    gcs = subprocess.Popen([sys.executable, "-c", GROUND_STATION, f"udpin:127.0.0.1:{port}"],
                           stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                           env={"MAVLINK20": "1", "PATH": "/usr/bin:/bin"})
    try:
        assert gcs.stdout is not None
        assert gcs.stdout.readline().strip() == "listening"
        # --skip-calibration: the ground station waits 30 s for a first message, which the
        # calibration run before the flight can outlast on a loaded machine
        assert main(["run", GPS_VARIO, "--emulate", "thermal", "--duration", "6", "--quiet",
                     "--skip-calibration", "--mavlink", f"udpout:127.0.0.1:{port}"]) == 0
        out, err = gcs.communicate(timeout=60)
    finally:
        gcs.kill()
    report = json.loads(out.strip().splitlines()[-1])
    assert set(report["seen"]) == {"HEARTBEAT", "HIGHRES_IMU", "SCALED_PRESSURE",
                                   "ATTITUDE_QUATERNION", "GLOBAL_POSITION_INT"}, err
    assert all(ids == [1, 1] for ids in report["seen"].values())
    assert report["target"][0] == 1  # the client took the board as its vehicle


@pytest.mark.parametrize("spec", ["udp:14550", "udpout:127.0.0.1", "udpout::14550",
                                  "udpout:127.0.0.1:0", "udpout:127.0.0.1:70000"])
def test_a_wrong_output_is_one_error_naming_the_form(spec: str) -> None:
    with pytest.raises(ImuhalError, match="udpout:HOST:PORT"):
        parse_udpout(spec)


def test_the_profile_ids_and_rate_reach_the_wire() -> None:
    rx = Receiver()
    try:
        sink = MavlinkSink({"output": f"udpout:127.0.0.1:{rx.port}",
                            "mavlink": {"system_id": 42, "component_id": 200,
                                        "mav_type": 7}})
        sink.handle(_gyro_sample(0))
        sink.close()
        while not rx.messages:
            threading.Event().wait(0.01)
    finally:
        rx.stop()
    (beat, *_rest) = rx.messages
    assert (beat.get_srcSystem(), beat.get_srcComponent(), beat.type) == (42, 200, 7)


def _gyro_sample(t_ns: int) -> Any:
    from imuhal.core.samples import Frame, GyroSample

    return GyroSample(t_ns=t_ns, device="imu", frame=Frame.BODY_NED,
                      gyro_rad_s=(0.0, 0.0, math.pi))
