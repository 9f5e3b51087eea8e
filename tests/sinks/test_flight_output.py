"""The seed GPS vario, emulated end to end, as a flight app sees it.

A reader opens the pseudo-terminal from the other side (as XCSoar opens a serial device)
and a client connects to the TCP port, both while the run goes; every sentence they receive
is parsed by hand (tests/sinks/nmea_reader.py) and each field compared with the event that
produced it: the latest vario estimate, pressure and temperature sample, GNSS fix.
"""

from __future__ import annotations

import math
import os
import socket
import time
from collections import Counter
from datetime import datetime, timezone
from pathlib import Path

import pytest

pytest.importorskip("pynmea2", reason="the gps extra (pynmea2, pyubx2) is not installed")

from tests.sinks.nmea_reader import read_lxwp0, read_sentence

from imuhal.core.atmosphere import altitude_m_from_pressure
from imuhal.core.samples import (
    PositionSample,
    PressureSample,
    TemperatureSample,
    VelocitySample,
)
from imuhal.emulation import open_emulated
from imuhal.estimation.outputs import VerticalEstimate
from imuhal.plugins.manager import load_registry
from imuhal.profile.bundled import bundled_profiles
from imuhal.profile.loader import load_profile
from imuhal.sinks.flight.sentences import KNOTS_PER_M_S, course_and_speed
from imuhal.sinks.flight.sink import FlightSink
from imuhal.sinks.flight.transports import PtyTransport, TcpTransport

FLIGHT_S = 12.0


class App:
    """One flight app's view: bytes in, complete lines out."""

    def __init__(self, read) -> None:
        self.read = read
        self.buffer = b""
        self.lines: list[str] = []

    def drain(self) -> list[str]:
        while True:
            data = self.read()
            if not data:
                break
            self.buffer += data
        *complete, self.buffer = self.buffer.split(b"\n")
        new = [c.decode("ascii") for c in complete]
        self.lines += new
        return new


def _pty_reader(path: str):
    fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK | os.O_NOCTTY)

    def read() -> bytes:
        try:
            return os.read(fd, 65536)
        except BlockingIOError:
            return b""
    return fd, read


def _tcp_reader(port: int):
    sock = socket.create_connection(("127.0.0.1", port), timeout=2)
    sock.setblocking(False)

    def read() -> bytes:
        try:
            return sock.recv(65536)
        except BlockingIOError:
            return b""
    return sock, read


class Latest:
    def __init__(self) -> None:
        self.vertical: VerticalEstimate | None = None
        self.pressure: PressureSample | None = None
        self.temperature: TemperatureSample | None = None
        self.position: PositionSample | None = None
        self.velocity: VelocitySample | None = None
        self.lxwp0_times: list[int] = []
        """The estimate each LXWP0 carried (both apps')."""

    def take(self, event: object) -> None:
        if isinstance(event, VerticalEstimate) and event.source == "vario":
            self.vertical = event
        elif isinstance(event, PressureSample) and event.valid:
            self.pressure = event
        elif isinstance(event, TemperatureSample) and event.valid and event.device == "baro":
            self.temperature = event
        elif isinstance(event, PositionSample) and event.valid:
            self.position = event
        elif isinstance(event, VelocitySample) and event.valid:
            self.velocity = event


def check(line: str, now: Latest, seen: dict[str, int]) -> None:
    """Every field of ``line`` against the events that produced it."""
    head, f = read_sentence(line)
    seen[head] = seen.get(head, 0) + 1
    v, p = now.vertical, now.pressure
    if head == "LK8EX1":
        assert int(f[0]) == round(p.pressure_pa)
        assert int(f[1]) == round(v.altitude_m)
        assert int(f[2]) == round(v.climb_m_s * 100)
        t = now.temperature
        assert f[3] == ("99" if t is None else str(round(t.temperature_degc)))  # 99: none yet
        assert f[4] == "999"
    elif head == "POV":
        pairs = dict(zip(f[::2], f[1::2], strict=True))
        assert float(pairs["P"]) == pytest.approx(p.pressure_pa / 100, abs=0.005)
        assert "E" not in pairs  # no airspeed, so no total energy: XCSoar uses P
        if now.temperature is None:
            assert "T" not in pairs
        else:
            assert float(pairs["T"]) == pytest.approx(now.temperature.temperature_degc,
                                                      abs=0.005)
    elif head == "LXWP0":
        got = read_lxwp0(line)
        # one fresh value: the estimate of this instant, the other five slots empty
        assert got["vario_m_s"] == pytest.approx(v.climb_m_s, abs=0.005)
        assert [got[f"vario{k}"] for k in range(2, 7)] == [None] * 5
        assert got["pressure_altitude_m"] == pytest.approx(
            altitude_m_from_pressure(p.pressure_pa), abs=0.05)
        now.lxwp0_times.append(v.t_ns)
    elif head == "_PRS":
        assert int(f[0], 16) == round(p.pressure_pa)
    elif head == "XCTRC":
        pos = now.position
        utc = datetime.fromtimestamp(pos.utc_s, tz=timezone.utc)
        assert [int(x) for x in f[:7]] == [utc.year, utc.month, utc.day, utc.hour,
                                           utc.minute, utc.second, utc.microsecond // 10_000]
        assert float(f[7]) == pytest.approx(pos.latitude_deg, abs=1e-6)
        assert float(f[8]) == pytest.approx(pos.longitude_deg, abs=1e-6)
        assert float(f[9]) == pytest.approx(pos.height_m, abs=0.005)
        if now.velocity is None:  # the first epoch with a fix can precede its velocity
            assert f[10:12] == ["", ""]
        else:
            course, speed = course_and_speed(now.velocity.velocity_ned_m_s)
            assert float(f[10]) == pytest.approx(speed, abs=0.005)
            assert float(f[11]) == pytest.approx(course, abs=0.005)
        assert float(f[12]) == pytest.approx(v.climb_m_s, abs=0.005)
        assert float(f[16]) == pytest.approx(p.pressure_pa / 100, abs=0.005)
    elif head == "GPGGA":
        pos = now.position
        lat = int(f[1][:2]) + float(f[1][2:]) / 60
        lon = int(f[3][:3]) + float(f[3][3:]) / 60
        assert (f[2], f[4]) == ("N", "E")
        assert lat == pytest.approx(pos.latitude_deg, abs=2e-6)
        assert lon == pytest.approx(pos.longitude_deg, abs=2e-6)
        assert (f[5], int(f[6]), float(f[8])) == ("1", pos.satellites,
                                                  round(pos.height_m, 1))
    elif head == "GPRMC":
        course, speed = course_and_speed(now.velocity.velocity_ned_m_s)
        assert f[1] == "A"
        assert float(f[6]) == pytest.approx(speed * KNOTS_PER_M_S, abs=0.005)
        assert float(f[7]) == pytest.approx(course, abs=0.005)
    else:
        raise AssertionError(f"unexpected sentence {line!r}")


def test_a_flight_app_on_the_pty_and_one_on_tcp_read_sentences_matching_the_estimates(
        tmp_path: Path) -> None:
    registry = load_registry()
    profile = load_profile(bundled_profiles()["seed-gps-vario.yaml"], registry)
    pty = PtyTransport(tmp_path / "vario")
    tcp = TcpTransport(0)
    fd, read_pty = _pty_reader(pty.path)
    sock, read_tcp = _tcp_reader(tcp.port)
    apps = [App(read_pty), App(read_tcp)]
    sinks = [FlightSink(transport=pty), FlightSink(transport=tcp)]
    now = Latest()
    seen: list[dict[str, int]] = [{}, {}]
    try:
        with open_emulated(profile, registry, scenario="thermal") as pipeline:
            for event in pipeline.events(FLIGHT_S):
                now.take(event)
                for sink in sinks:
                    sink.handle(event)
                for app, counts in zip(apps, seen, strict=True):
                    for line in app.drain():
                        check(line, now, counts)
    finally:
        for sink in sinks:
            sink.close()
        os.close(fd)
        sock.close()
    assert not (tmp_path / "vario").exists()  # the link goes with the run
    for counts in seen:
        assert set(counts) == {"LK8EX1", "LXWP0", "POV", "_PRS", "XCTRC", "GPGGA", "GPRMC"}
        assert now.temperature is not None  # the MS5611's temperature reached the sentences
        # rate limits: 10 Hz vario sentences, _PRS every 48 ms, one GGA/RMC per 5 Hz epoch
        assert 10 * (FLIGHT_S - 3) < counts["LK8EX1"] <= 10 * FLIGHT_S + 1
        assert counts["POV"] == counts["LK8EX1"] == counts["LXWP0"]
        assert (FLIGHT_S - 3) / 0.048 < counts["_PRS"] <= FLIGHT_S / 0.048 + 1
        assert 5 * (FLIGHT_S - 3) < counts["GPGGA"] == counts["GPRMC"] <= 5 * FLIGHT_S
    # a fresh estimate in every LXWP0: each estimate sent once to each of the two apps
    assert set(Counter(now.lxwp0_times).values()) == {2}
    assert sinks[0].transport.dropped_bytes == 0 and sinks[1].transport.dropped_bytes == 0
    assert not math.isnan(now.vertical.climb_m_s)


def test_a_pty_link_never_replaces_a_users_file(tmp_path: Path) -> None:
    from imuhal.core.errors import ImuhalError

    precious = tmp_path / "notes.txt"
    precious.write_text("keep me")
    with pytest.raises(ImuhalError, match="not a symlink"):
        PtyTransport(precious)
    assert precious.read_text() == "keep me"


@pytest.mark.parametrize("spec", ["tcp:notaport", "serial:/dev/ttyUSB0", "udp:1234", "tcp:70000"])
def test_a_malformed_output_names_the_forms(spec: str) -> None:
    from imuhal.core.errors import ImuhalError
    from imuhal.sinks.flight.transports import open_transport

    with pytest.raises(ImuhalError, match=spec.split(":")[0]):
        open_transport(spec)


def test_a_serial_output_that_does_not_exist_is_one_clear_error() -> None:
    from imuhal.core.errors import ImuhalError
    from imuhal.sinks.flight.transports import open_transport

    with pytest.raises(ImuhalError, match="cannot open /dev/imuhal-missing"):
        open_transport("serial:/dev/imuhal-missing@115200")


def test_checking_an_output_opens_nothing(tmp_path: Path) -> None:
    """A run checks its --nmea outputs before it starts: no link made, no port bound."""
    from imuhal.sinks.flight.transports import check_transport

    link = tmp_path / "vario"
    assert check_transport(f"pty:{link}").kind == "pty"
    assert not link.exists() and not link.is_symlink()
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        s.listen(1)
        taken = s.getsockname()[1]
        spec = check_transport(f"tcp:{taken}")  # a port in use is found only when opened
        assert (spec.kind, spec.where, spec.number) == ("tcp", "127.0.0.1", taken)


def test_the_serial_transport_writes_sentences_a_device_reads(tmp_path: Path) -> None:
    """pyserial on one end of a pty stands in for a UART; the other end reads."""
    from imuhal.sinks.flight.sentences import lk8ex1
    from imuhal.sinks.flight.transports import open_transport

    master, slave = os.openpty()
    import tty

    tty.setraw(slave)
    transport = open_transport(f"serial:{os.ttyname(slave)}@115200")
    try:
        sink = FlightSink({"sentences": ("LK8EX1",)}, transport=transport)
        sink.handle(PressureSample(t_ns=0, device="baro", pressure_pa=95000.4))
        sink.handle(VerticalEstimate(t_ns=0, source="vario", altitude_m=510.2, climb_m_s=0.73))
        sink.handle(VerticalEstimate(t_ns=50_000_000, source="vario", altitude_m=510.3,
                                     climb_m_s=0.9))  # within 100 ms: rate-limited away
        sink.handle(VerticalEstimate(t_ns=100_000_000, source="vario", altitude_m=510.4,
                                     climb_m_s=1.1))
        got = b""
        deadline = time.monotonic() + 2
        while got.count(b"\n") < 2 and time.monotonic() < deadline:
            got += os.read(master, 4096)
        lines = got.decode().splitlines()
        assert lines == [lk8ex1(pressure_pa=95000.4, altitude_m=510.2, climb_m_s=0.73,
                                temperature_degc=None).strip(),
                         lk8ex1(pressure_pa=95000.4, altitude_m=510.4, climb_m_s=1.1,
                                temperature_degc=None).strip()]
        assert [read_sentence(line)[1][2] for line in lines] == ["73", "110"]
    finally:
        transport.close()
        os.close(master)
        os.close(slave)
