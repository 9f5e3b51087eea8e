"""The serial backend through pyserial against a real pseudo-terminal."""

from __future__ import annotations

import os
import threading

import pytest

from imuhal.bus.serial_port import SerialBus
from imuhal.core.errors import BusError

pytestmark = pytest.mark.skipif(not hasattr(os, "openpty"), reason="needs a POSIX pty")


def test_a_transfer_writes_then_reads_the_peer_answer() -> None:
    master, slave = os.openpty()
    name = os.ttyname(slave)

    def peer() -> None:
        request = os.read(master, 2)
        os.write(master, request[::-1] + b"!")

    t = threading.Thread(target=peer)
    t.start()
    bus = SerialBus(name, baudrate=115200, timeout_s=2.0)
    try:
        assert bus.transfer(0, b"ab", 3) == b"ba!"
    finally:
        bus.close()
        t.join(timeout=2)
        os.close(master)
        os.close(slave)


def test_a_silent_peer_is_a_timeout_error() -> None:
    master, slave = os.openpty()
    bus = SerialBus(os.ttyname(slave), timeout_s=0.05)
    try:
        with pytest.raises(BusError, match="timeout"):
            bus.transfer(0, b"", 4)
    finally:
        bus.close()
        os.close(master)
        os.close(slave)


def test_a_missing_port_is_one_line_naming_the_port_and_what_to_check() -> None:
    with pytest.raises(BusError, match="cannot open /dev/ttyDOESNOTEXIST") as caught:
        SerialBus("/dev/ttyDOESNOTEXIST")
    message = str(caught.value)
    assert "\n" not in message and "port" in message and "dialout" in message


class _SlowLine:
    """A port at 9600 baud as pyserial drives it: ``write`` queues the bytes in the transmit
    buffer, ``flush`` (tcdrain) would wait until the line has sent them."""

    def __init__(self) -> None:
        self.queued = b""

    def write(self, data: bytes) -> int:
        self.queued += data
        return len(data)

    def flush(self) -> None:
        raise AssertionError("the write waited for the line to send its bytes (tcdrain)")

    def close(self) -> None:
        pass


def test_a_write_is_queued_for_the_line_without_waiting_for_it_to_leave() -> None:
    """A UBX CFG message of 16 bytes takes 17 ms to leave at 9600 baud; the transfer hands
    it to the transmit buffer and returns, so a driver writing to its receiver does not
    hold a 200 Hz IMU on the same thread (issue 26)."""
    port = _SlowLine()
    bus = SerialBus("/dev/ttyS-fake", baudrate=9600, serial_factory=lambda *a, **k: port)
    frame = bytes(range(16))
    assert bus.transfer(0, frame, 0) == b""
    assert port.queued == frame
