"""A UART in a recording: what the driver saw of it (baud changes, writes, the bytes that
had arrived, failures) is what a replay gives back, on pyserial's own loopback port."""

from __future__ import annotations

from pathlib import Path

import pytest
import serial

from imuhal.bus.recording.format import open_recording
from imuhal.bus.recording.recorder import BusRecorder
from imuhal.bus.serial_port import SerialBus
from imuhal.bus.spy import SpyBus
from imuhal.core.clock import SimulatedClock
from imuhal.core.errors import BusError
from imuhal.offline.replay import ReplayDivergence, ReplaySource, replay_bus


def _record_loopback(path: Path) -> tuple[bytes, str]:
    """Talk to a loopback UART through the recording spy, unplug it, read once more.
    Returns what was received and the error the unplugged port raised."""
    port = serial.serial_for_url("loop://", timeout=0.1)
    uart = SerialBus("loop://", serial_factory=lambda *_a, **_k: port)
    recorder = BusRecorder(path, {"what": "test"})
    recorder.attach({"uart": uart})
    spy = SpyBus(uart, recorder.on_transfer, SimulatedClock(1_000))
    spy.set_baudrate(115200)  # type: ignore[attr-defined]
    spy.transfer(0, b"$GPTXT,hello*00\r\n", 0)
    got = spy.receive(0, 64)
    port.close()  # the USB adapter is pulled out
    with pytest.raises(BusError) as unplugged:
        spy.receive(0, 64)
    recorder.close()
    return got, str(unplugged.value)


def _replayed_uart(path: Path) -> SpyBus:
    source = ReplaySource(open_recording(path))
    return replay_bus(source.buses[0], source)  # type: ignore[return-value]


def test_a_uarts_baud_change_writes_received_bytes_and_failure_replay_as_recorded(
        tmp_path: Path) -> None:
    got, error = _record_loopback(tmp_path / "uart.imurec")
    assert got == b"$GPTXT,hello*00\r\n"
    uart = _replayed_uart(tmp_path / "uart.imurec")
    uart.set_baudrate(115200)  # type: ignore[attr-defined]
    assert uart.transfer(0, b"$GPTXT,hello*00\r\n", 0) == b""
    assert uart.receive(0, 64) == got
    with pytest.raises(BusError) as again:
        uart.receive(0, 64)
    assert str(again.value) == error


def test_a_replay_that_changes_the_baud_rate_differently_names_the_transaction(
        tmp_path: Path) -> None:
    _record_loopback(tmp_path / "uart.imurec")
    uart = _replayed_uart(tmp_path / "uart.imurec")
    with pytest.raises(ReplayDivergence, match=r"^replay diverged at transaction 0 \(t=0\.000001"
                       r" s\): the recording has serial://loop:// BAUD 115200, the driver asked "
                       r"serial://loop:// BAUD 9600$"):
        uart.set_baudrate(9600)  # type: ignore[attr-defined]


def test_a_replay_that_reads_a_uart_where_the_recording_wrote_names_the_transaction(
        tmp_path: Path) -> None:
    _record_loopback(tmp_path / "uart.imurec")
    uart = _replayed_uart(tmp_path / "uart.imurec")
    uart.set_baudrate(115200)  # type: ignore[attr-defined]
    with pytest.raises(ReplayDivergence, match=r"transaction 1 .*the recording has "
                       r"serial://loop:// @00 W:24 47 .* R\(0\), the driver asked "
                       r"serial://loop:// @00 RX\(64\)$"):
        uart.receive(0, 64)
