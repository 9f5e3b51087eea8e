"""Bluetooth LE framing over the transport's peripheral interface, without a radio: the
sentences a central rebuilds from the Nordic UART notifications (concatenated, split at
CR LF) are the ones written, in order, in notifications of at most ATT_MTU - 3 bytes; a
radio that falls behind loses whole sentences, counted; the Environmental Sensing pressure
is uint32 0.1 Pa. What is NOT tested here: bless and BlueZ themselves (BlessPeripheral),
advertising, pairing, MTU exchange, and a phone's app (docs/flight-instrument.md)."""

from __future__ import annotations

import struct
import sys

import pytest
from tests.sinks.nmea_reader import read_lxwp0, read_sentence

from imuhal.emulation import open_emulated
from imuhal.plugins.manager import load_registry
from imuhal.profile.bundled import bundled_profiles
from imuhal.profile.loader import load_profile
from imuhal.sinks.flight import sentences as fmt
from imuhal.sinks.flight.ble import (
    BLE_SENTENCES,
    ESS_PRESSURE,
    ESS_SERVICE,
    NUS_SERVICE,
    NUS_TX,
    BleTransport,
)
from imuhal.sinks.flight.sink import FlightSink


class FakePeripheral:
    """Records every notification, as a subscribed central receives them; ``stalled`` holds
    them back (the radio's queue) until ``release``."""

    description = "test peripheral"

    def __init__(self) -> None:
        self.sent: list[tuple[str, str, bytes]] = []
        self.queued: list[tuple[str, str, bytes]] = []
        self.stalled = False
        self.closed = False

    def notify(self, service_uuid: str, char_uuid: str, value: bytes) -> None:
        (self.queued if self.stalled else self.sent).append((service_uuid, char_uuid, value))

    def backlog(self) -> int:
        return len(self.queued)

    def release(self) -> None:
        self.sent += self.queued
        self.queued.clear()

    def close(self) -> None:
        self.closed = True

    def tx(self) -> list[bytes]:
        return [v for s, c, v in self.sent if (s, c) == (NUS_SERVICE, NUS_TX)]


def central_lines(notifications: list[bytes]) -> list[str]:
    """What a phone does: concatenate the TX notifications, split at CR LF."""
    text = b"".join(notifications).decode("ascii")
    assert text.endswith("\r\n")
    return [line + "\r\n" for line in text.split("\r\n")[:-1]]


SENTENCES = [fmt.lk8ex1(pressure_pa=95000 + k, altitude_m=500 + k, climb_m_s=k / 10,
                        temperature_degc=20) if k % 2 else
             fmt.lxwp0(pressure_altitude_m=500.0 + k, climb_m_s=k / 10) for k in range(40)]


@pytest.mark.parametrize("chunk", [20, 64, 182])
def test_sentences_arrive_whole_and_in_order_in_mtu_sized_notifications(chunk: int) -> None:
    radio = FakePeripheral()
    ble = BleTransport(radio, chunk_bytes=chunk)
    for text in SENTENCES:
        ble.write(text.encode("ascii"))
    tx = radio.tx()
    assert all(1 <= len(n) <= chunk for n in tx)
    assert central_lines(tx) == SENTENCES
    # each sentence starts a notification: no notification carries two sentences' bytes
    assert sum(1 for n in tx if n.startswith(b"$")) == len(SENTENCES)
    assert ble.notifications == len(tx) and ble.dropped_bytes == 0


def test_a_radio_that_falls_behind_loses_whole_sentences_counted() -> None:
    radio = FakePeripheral()
    ble = BleTransport(radio, max_backlog=8)
    radio.stalled = True
    for text in SENTENCES:
        ble.write(text.encode("ascii"))
    radio.release()
    lines = central_lines(radio.tx())
    assert 0 < len(lines) < len(SENTENCES)
    assert all(line in SENTENCES for line in lines)  # nothing cut: every line parses
    for line in lines:
        read_sentence(line)
    lost = [s for s in SENTENCES if s not in lines]
    assert ble.dropped_bytes == sum(len(s) for s in lost)


def test_the_pressure_characteristic_is_uint32_tenths_of_pa_at_its_rate() -> None:
    radio = FakePeripheral()
    ble = BleTransport(radio, pressure_hz=10)
    for k in range(50):  # 50 Hz for 1 s
        ble.set_pressure_pa(95123.44 + k, t_ns=k * 20_000_000)
    ess = [v for s, c, v in radio.sent if (s, c) == (ESS_SERVICE, ESS_PRESSURE)]
    assert len(ess) == 10
    assert [struct.unpack("<I", v)[0] for v in ess[:2]] == [951234, 951284]  # k = 0 and 5


def test_chunks_below_the_default_mtu_are_refused() -> None:
    from imuhal.core.errors import ImuhalError

    with pytest.raises(ImuhalError, match="use 20"):
        BleTransport(FakePeripheral(), chunk_bytes=10)


@pytest.mark.slow
def test_the_gps_varios_flight_reaches_a_central_as_lk8ex1_and_lxwp0_at_10_hz() -> None:
    pytest.importorskip("pyubx2", reason="the gps extra (pynmea2, pyubx2) is not installed")
    registry = load_registry()
    profile = load_profile(bundled_profiles()["seed-gps-vario.yaml"], registry)
    radio = FakePeripheral()
    sink = FlightSink({"sentences": BLE_SENTENCES}, transport=BleTransport(radio))
    with open_emulated(profile, registry, scenario="thermal") as pipeline:
        pipeline.run(6.0, [sink])
    assert radio.closed
    lines = central_lines(radio.tx())
    heads = [read_sentence(line)[0] for line in lines]
    assert set(heads) == {"LK8EX1", "LXWP0"}
    assert 10 * 4 < heads.count("LXWP0") == heads.count("LK8EX1") <= 10 * 6 + 1
    assert all(read_lxwp0(line)["vario_m_s"] is not None
               for line in lines if line.startswith("$LXWP0"))
    ess = [v for s, c, v in radio.sent if c == ESS_PRESSURE]
    assert 10 * 4 < len(ess) <= 10 * 6 + 1
    assert 80_000 < struct.unpack("<I", ess[-1])[0] / 10 < 105_000


def test_ble_without_bless_is_a_one_line_error(monkeypatch: pytest.MonkeyPatch) -> None:
    from imuhal.core.errors import ImuhalError
    from imuhal.sinks.flight.transports import open_transport

    monkeypatch.setitem(sys.modules, "bless", None)  # as if not installed
    with pytest.raises(ImuhalError, match=r"pip install 'imuhal\[ble\]'"):
        open_transport("ble")
