"""The GNSS driver against its byte-stream emulator, and against a real pseudo-terminal.

Faults go through the emulator's documented settings (``lose_fix``, ``corrupt_checksums``,
``cut_next_frame``, ``model``, its baud rate); nothing is monkeypatched.
"""

from __future__ import annotations

import os
import struct
import threading
import time

import numpy as np
import pytest

pytest.importorskip("pynmea2", reason="the gps extra (pynmea2, pyubx2) is not installed")
pytest.importorskip("pyubx2", reason="the gps extra (pynmea2, pyubx2) is not installed")

from imuhal.bus.base import BusKind
from imuhal.bus.serial_port import SerialBus
from imuhal.core.clock import MonotonicClock, SimulatedClock
from imuhal.core.errors import BusError, DeviceNotFoundError
from imuhal.core.samples import (
    FixType,
    PositionSample,
    SampleFlag,
    VelocitySample,
)
from imuhal.emulation import EmulatedBus
from imuhal.plugins.manager import load_registry
from imuhal.sim.world import physical_inputs
from imuhal_chips.gnss.driver import GnssDriver, GnssSettings
from imuhal_chips.gnss.emulator import GnssEmulator, GnssErrorModel
from imuhal_chips.gnss.integrity import CONFIRM

EARTH_R_M = 6_371_000.0


def rig(**settings):
    clock = SimulatedClock()
    bus = EmulatedBus("emul://uart", BusKind.SERIAL)
    emulator = bus.attach(0, GnssEmulator(clock=clock))
    driver = GnssDriver(bus.link(0), GnssSettings(**settings), device="gps", clock=clock)
    return clock, emulator, driver


def fly(clock, emulator, driver, seconds, scenario=None):
    """Poll like the pipeline does, handing the emulator the truth before each poll."""
    scenario = scenario or load_registry().scenarios.get("thermal")(seed=1)
    out = []
    t = clock.now_ns()
    end = t + round(seconds * 1e9)
    while t < end:
        clock.sleep_until(t)
        emulator.set_physics(physical_inputs(scenario.truth(t / 1e9)))
        result = driver.poll(t)
        out += result.samples
        t = result.next_poll_ns
    return out, scenario


def started(**settings):
    clock, emulator, driver = rig(**settings)
    driver.probe()
    driver.configure()
    return clock, emulator, driver


def test_probe_finds_a_factory_receiver_speaking_nmea_at_9600() -> None:
    _, _, driver = rig()
    ident = driver.probe()
    assert ident.identity == "NMEA at 9600 baud" and driver.protocol == "nmea"


def test_probe_finds_the_baud_rate_the_receiver_uses() -> None:
    _, emulator, driver = rig(baud_rates=(9600, 38400, 115200))
    emulator.baudrate = 38400
    assert driver.probe().identity == "NMEA at 38400 baud"


def test_a_baud_mismatch_is_a_clear_error_naming_port_rates_and_what_was_seen() -> None:
    _, emulator, driver = rig(baud_rates=(9600, 4800))
    emulator.baudrate = 115200
    with pytest.raises(DeviceNotFoundError) as err:
        driver.probe()
    text = str(err.value)
    assert "emul://uart" in text and "[9600, 4800]" in text
    assert "9600: " in text and "wrong baud rate?" in text and "baud_rates" in text


def test_a_silent_port_says_nothing_was_received() -> None:
    _, emulator, driver = rig(baud_rates=(9600,))
    emulator.absent = True
    with pytest.raises(DeviceNotFoundError, match="9600: nothing received"):
        driver.probe()


def test_a_port_that_does_not_exist_is_a_bus_error_naming_it() -> None:
    with pytest.raises(BusError, match="/dev/imuhal-no-such-port"):
        SerialBus("/dev/imuhal-no-such-port", baudrate=9600)


def test_configure_switches_a_u_blox_receiver_to_nav_pvt_and_checks_each_ack() -> None:
    clock, emulator, driver = started(protocol="ubx", rate_hz=5)
    assert emulator.nav_pvt and emulator.nmea_enabled == set() and emulator.rate_hz == 5
    samples, _ = fly(clock, emulator, driver, 4)
    valid = [s for s in samples if isinstance(s, PositionSample) and s.valid]
    assert valid and valid[-1].horizontal_accuracy_m == 2.5  # accuracies only UBX reports
    assert driver.stats.sentences == 0 and driver.stats.checksum_errors == 0


def test_a_recovery_reconfigures_the_receiver_a_poll_at_a_time_never_waiting_on_the_clock(
        ) -> None:
    """After a restart the receiver speaks factory NMEA at 1 Hz and answers each CFG message
    behind it: seconds at 9600 baud. ``recover`` and every poll of the recovery return at
    once (the simulated clock does not move inside them), give no samples, and leave the
    receiver configured as at start-up."""
    from imuhal.core.errors import ConfigurationError

    clock, emulator, driver = started(protocol="ubx", rate_hz=5)
    fly(clock, emulator, driver, 3)
    emulator.silent_reset()
    with pytest.raises(ConfigurationError, match="restarted"):
        fly(clock, emulator, driver, 5)
    start_ns = clock.now_ns()
    next_ns = driver.recover(start_ns)
    assert clock.now_ns() == start_ns
    polls = 0
    while driver.health.reconfigurations == 0:
        clock.sleep_until(next_ns)
        before = clock.now_ns()
        result = driver.poll(before)
        assert clock.now_ns() == before and result.samples == []
        next_ns = result.next_poll_ns
        polls += 1
    assert clock.now_ns() - start_ns > 0.3e9 and polls > 10
    assert emulator.nav_pvt and emulator.nmea_enabled == set() and emulator.rate_hz == 5
    samples, _ = fly(clock, emulator, driver, 2)
    assert [s for s in samples if isinstance(s, PositionSample) and s.valid
            and s.horizontal_accuracy_m == 2.5]


def test_no_fix_before_the_time_to_first_fix_is_flagged_never_valid() -> None:
    clock, emulator, driver = started()
    emulator.use_model(GnssErrorModel(time_to_first_fix_s=6.0))
    samples, _ = fly(clock, emulator, driver, 10)
    pos = [s for s in samples if isinstance(s, PositionSample)]
    early = [s for s in pos if s.t_ns < 5.9e9]
    first = [s for s in pos if s.t_ns > 5.9e9]
    assert early and all(s.fix_type is FixType.NO_FIX and SampleFlag.STALE in s.flags
                         for s in early)
    # the first fix is valid once the next epochs follow it (imuhal_chips.gnss.integrity)
    assert [s.valid for s in first[:CONFIRM]] == [False] * (CONFIRM - 1) + [True]
    assert all(s.valid for s in first[CONFIRM:])
    assert not [s for s in samples if isinstance(s, VelocitySample) and s.t_ns < 5.9e9]


def test_a_fix_lost_interval_flags_those_epochs_and_the_run_goes_on() -> None:
    clock, emulator, driver = started(protocol="ubx", rate_hz=5)
    emulator.lose_fix(5.0, 8.0)
    samples, _ = fly(clock, emulator, driver, 12)
    pos = [s for s in samples if isinstance(s, PositionSample)]
    lost = [s for s in pos if 5.2e9 < s.t_ns < 7.9e9]
    assert lost and all(not s.valid and s.fix_type is FixType.NO_FIX for s in lost)
    assert all(s.valid for s in pos if s.t_ns > 8.3e9)
    assert any(s.valid for s in pos if s.t_ns > 11e9)


def test_wrong_checksums_are_flagged_counted_and_never_valid() -> None:
    clock, emulator, driver = started()
    fly(clock, emulator, driver, 3)
    emulator.corrupt_checksums(3)
    samples, _ = fly(clock, emulator, driver, 4)
    bad = [s for s in samples if SampleFlag.CRC_ERROR in s.flags]
    assert len(bad) == 3 and driver.stats.checksum_errors == 3
    assert all(not s.valid for s in bad)
    assert sum(s.valid for s in samples if isinstance(s, PositionSample)) >= 2


def test_a_ubx_frame_cut_in_half_is_flagged_and_the_next_ones_decode() -> None:
    clock, emulator, driver = started(protocol="ubx", rate_hz=5)
    fly(clock, emulator, driver, 2)
    emulator.cut_next_frame()
    samples, _ = fly(clock, emulator, driver, 3)
    assert driver.stats.checksum_errors == 1
    assert [s for s in samples if SampleFlag.CRC_ERROR in s.flags]
    assert sum(s.valid for s in samples if isinstance(s, PositionSample)) >= 12


def test_dropouts_lose_epochs_without_inventing_any() -> None:
    clock, emulator, driver = started(protocol="ubx", rate_hz=5)
    emulator.use_model(GnssErrorModel(dropout_probability=0.4, seed=3))
    samples, _ = fly(clock, emulator, driver, 20)
    n = sum(isinstance(s, PositionSample) for s in samples)
    assert 0.4 * 100 < n < 0.8 * 100
    fixes = [s for s in samples if isinstance(s, PositionSample)]
    assert all(s.valid for s in samples if s.t_ns >= fixes[CONFIRM - 1].t_ns)


def _ned(lat: float, lon: float, h: float, model: GnssErrorModel) -> np.ndarray:
    """NED offset from the origin on a sphere (error < 0.5 % of the offset: enough here)."""
    north = np.radians(lat - model.origin_latitude_deg) * EARTH_R_M
    east = np.radians(lon - model.origin_longitude_deg) * EARTH_R_M * np.cos(
        np.radians(model.origin_latitude_deg))
    return np.array([north, east, -(h - model.origin_height_msl_m)])


def test_fixes_follow_the_truth_within_the_reported_accuracy() -> None:
    clock, emulator, driver = started(protocol="ubx", rate_hz=5, latency_s=0.08)
    model = emulator.model
    samples, scenario = fly(clock, emulator, driver, 40)
    pos = [s for s in samples if isinstance(s, PositionSample) and s.valid]
    vel = [s for s in samples if isinstance(s, VelocitySample)]
    assert len(pos) > 150
    err = np.array([_ned(s.latitude_deg, s.longitude_deg, s.height_m, model)
                    - scenario.truth(s.t_ns / 1e9).position_ned_m for s in pos])
    horizontal_rms = float(np.sqrt(np.mean(np.sum(err[:, :2] ** 2, axis=1))))
    vertical_rms = float(np.sqrt(np.mean(err[:, 2] ** 2)))
    # Bounds: three times the 1-sigma accuracy the receiver reports.
    assert horizontal_rms < 3 * model.horizontal_accuracy_m
    assert vertical_rms < 3 * model.vertical_accuracy_m
    verr = np.array([np.array(s.velocity_ned_m_s) - scenario.truth(s.t_ns / 1e9)
                     .velocity_ned_m_s for s in vel])
    # Velocity: 3 sigma of the noise plus what the thermal's turn changes within one
    # poll period (the epoch time is known to one poll, 50 ms).
    assert float(np.sqrt(np.mean(verr**2))) < 3 * model.speed_accuracy_m_s + 0.2


def test_the_emulators_nav_pvt_decoded_by_hand_matches_the_truth() -> None:
    """An independent reading of what the emulator sends: struct over the documented
    NAV-PVT layout, after enabling it with a CFG-MSG frame built by hand."""
    clock = SimulatedClock()
    bus = EmulatedBus("emul://uart", BusKind.SERIAL)
    emulator = bus.attach(0, GnssEmulator(clock=clock))
    body = bytes((0x06, 0x01, 3, 0, 0x01, 0x07, 1))
    a = b = 0
    for byte in body:
        a, b = (a + byte) & 0xFF, (b + ((a + byte) & 0xFF)) & 0xFF
    bus.transfer(0, b"\xb5\x62" + body + bytes((a, b)), 0)
    scenario = load_registry().scenarios.get("thermal")(seed=1)
    stream = bytearray()
    for k in range(0, 80):
        t = k * 50_000_000
        clock.sleep_until(t)
        emulator.set_physics(physical_inputs(scenario.truth(t / 1e9)))
        stream += bus.receive(0, 4096)
    i = stream.find(b"\xb5\x62\x05\x01")  # the ACK-ACK comes first
    assert stream[i + 6:i + 8] == b"\x06\x01"
    frames = []
    j = stream.find(b"\xb5\x62\x01\x07")
    while j >= 0:
        frames.append(bytes(stream[j + 6:j + 6 + 92]))
        j = stream.find(b"\xb5\x62\x01\x07", j + 1)
    fixed = [f for f in frames if f[20] == 3]
    assert len(frames) >= 3 and fixed
    p = fixed[-1]
    hour, minute, second = p[8], p[9], p[10]
    t_s = (hour * 3600 + minute * 60 + second + struct.unpack_from("<i", p, 16)[0] * 1e-9
           - (11 * 3600))
    lon, lat, _, h_msl = struct.unpack_from("<iiii", p, 24)
    vn, ve, vd = struct.unpack_from("<iii", p, 48)
    truth = scenario.truth(t_s)
    got = _ned(lat * 1e-7, lon * 1e-7, h_msl / 1000, emulator.model)
    assert np.linalg.norm(got - truth.position_ned_m) < 15.0
    assert np.allclose(np.array((vn, ve, vd)) / 1000, truth.velocity_ned_m_s, atol=0.6)


def test_the_driver_reads_published_sentences_from_a_real_pseudo_terminal() -> None:
    """pyserial on a pty slave, fed the classic GGA/RMC examples (known checksums) from the
    master side, the GGA then once a (simulated) second, each with its time moved on (a
    receiver whose time does not advance sends nothing new): the driver decodes them
    without any emulator."""
    master, slave = os.openpty()
    path = os.ttyname(slave)
    stop = threading.Event()
    first = (b"$GPRMC,123519,A,4807.038,N,01131.000,E,022.4,084.4,230394,003.1,W*6A\r\n"
             b"$GPGGA,123519,4807.038,N,01131.000,E,1,08,0.9,545.4,M,46.9,M,,*47\r\n")

    def gga(seconds: int) -> bytes:
        """The classic GGA ``seconds`` after 12:35:00."""
        minutes, second = divmod(seconds, 60)
        body = (f"GPGGA,{12 + (35 + minutes) // 60:02d}{(35 + minutes) % 60:02d}{second:02d},"
                "4807.038,N,01131.000,E,1,08,0.9,545.4,M,46.9,M,,")
        checksum = 0
        for char in body.encode():
            checksum ^= char
        return f"${body}*{checksum:02X}\r\n".encode()

    assert gga(19) == first.split(b"\n")[1] + b"\n"  # the XOR above is NMEA's

    def talk() -> None:
        k = 0
        while not stop.is_set():
            os.write(master, first if k == 0 else gga(19 + k))
            k += 1
            time.sleep(0.1)

    talker = threading.Thread(target=talk, daemon=True)
    talker.start()
    bus = SerialBus(path, baudrate=9600, timeout_s=0.2)
    try:
        clock = MonotonicClock()
        driver = GnssDriver(bus.link(0), GnssSettings(baud_rates=(9600,), probe_window_s=1.0,
                                                      configure_receiver=False, poll_hz=20),
                            device="gps", clock=clock)
        assert driver.probe().identity == "NMEA at 9600 baud"
        driver.configure()
        got: list = []
        deadline = time.monotonic() + 3.0
        # the first fix is valid once the epochs after it confirm it (integrity.py)
        while time.monotonic() < deadline and not [s for s in got if s.valid and
                                                   isinstance(s, PositionSample)]:
            got += driver.poll(clock.now_ns()).samples
            time.sleep(0.05)
        fix = next(s for s in got if s.valid and isinstance(s, PositionSample))
        assert fix.latitude_deg == pytest.approx(48.1173, abs=1e-6)
        assert fix.longitude_deg == pytest.approx(11.516667, abs=1e-6)
        assert (fix.height_m, fix.satellites) == (545.4, 8)
    finally:
        stop.set()
        talker.join()
        bus.close()
        os.close(master)
        os.close(slave)


@pytest.mark.slow
def test_a_receiver_that_restarts_in_factory_nmea_is_reconfigured_through_recovery() -> None:
    """Through the pipeline: the driver notices NMEA where it configured UBX, the pipeline
    recovers it (re-probe, reconfigure) and UBX fixes resume."""
    from imuhal.emulation import open_emulated
    from imuhal.profile.bundled import bundled_profiles
    from imuhal.profile.loader import load_profile

    registry = load_registry()
    profile = load_profile(bundled_profiles()["seed-gps-vario.yaml"], registry)
    with open_emulated(profile, registry, scenario="thermal") as pipeline:
        events = list(pipeline.events(10.0))
        pipeline.board.emulators["gps"].silent_reset()
        events = list(pipeline.events(20.0))
        driver = pipeline.devices["gps"].driver
        warnings = list(pipeline.warnings)
    assert driver.health.resets_detected == 1 and driver.health.reconfigurations == 1
    assert any("restarted" in w for w in warnings)
    fixes = [e for e in events if isinstance(e, PositionSample) and e.valid]
    assert fixes[-1].t_ns > 28e9 and fixes[-1].horizontal_accuracy_m == 2.5  # UBX again


def emulator_latency() -> float:
    return GnssErrorModel().latency_s


def test_an_nmea_burst_spread_over_many_reads_at_9600_baud_is_one_epoch() -> None:
    """RMC VTG GGA GSA take about 0.3 s at 9600 baud, six 20 Hz reads: still one fix per
    epoch, with what each sentence contributes (RMC time and date, GGA height and
    satellites, GSA 3D fix) and the velocity from RMC plus the change of height. With the
    receiver's output latency stated, epochs are time-stamped to within one read."""
    clock, emulator, driver = started(latency_s=emulator_latency())
    samples, scenario = fly(clock, emulator, driver, 12)
    fixes = [s for s in samples if isinstance(s, PositionSample)]
    pos = fixes[CONFIRM - 1:]  # the first fix is valid once the next epochs follow it
    vel = [s for s in samples if isinstance(s, VelocitySample)]
    assert 9 <= len(fixes) <= 12 and driver.stats.epochs == len(fixes)
    assert all(s.valid and s.satellites == 9 and s.fix_type is FixType.FIX_3D and s.utc_s
               for s in pos)
    assert len(vel) == len(fixes) - 1  # the first fix has no earlier height to difference
    for v in vel:
        epoch_s = round(v.t_ns / 1e9)  # the emulator measures on whole seconds at 1 Hz
        assert v.t_ns / 1e9 - epoch_s == pytest.approx(0.025, abs=0.026)
        truth = scenario.truth(epoch_s).velocity_ned_m_s
        assert np.hypot(*v.velocity_ned_m_s[:2]) == pytest.approx(np.hypot(*truth[:2]),
                                                                  abs=0.6)


def test_asking_more_than_the_line_carries_is_a_configuration_error_naming_the_fix() -> None:
    from imuhal.core.errors import ConfigurationError

    _, _, driver = rig(rate_hz=5)
    driver.probe()
    with pytest.raises(ConfigurationError, match=r"GGA, GSA, RMC, VTG at 5 Hz need about "
                       r"1500 bytes/s, but 9600 baud carries 960; lower rate_hz"):
        driver.configure()


def test_output_the_line_cannot_carry_is_dropped_by_the_receiver_not_queued_for_ever() -> None:
    """A receiver set to more than its line carries (10 Hz of NAV-PVT and four NMEA
    sentences at 9600 baud) keeps a bounded backlog: its transmit buffer drops whole
    messages, as a u-blox receiver does; the emulator's send queue used to grow without
    bound, holding every later message (and ACK) back by minutes."""
    from imuhal_chips.gnss.emulator import TX_BUFFER_BYTES

    clock, emulator, _ = rig()
    emulator.rate_hz, emulator.nav_pvt = 10.0, True
    backlog = []
    for k in range(1, 601):  # a host reading every 0.1 s for 60 s
        clock.sleep_until(k * 100_000_000)
        emulator.bus_receive(BusKind.SERIAL, 4096)
        backlog.append(emulator.backlog_bytes)
    assert max(backlog) <= TX_BUFFER_BYTES
    assert emulator.messages_dropped > 0
