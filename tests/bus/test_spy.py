"""The spy bus records every transaction without changing it."""

from __future__ import annotations

import pytest
from tests.support.testchip import TC3Emulator

from imuhal.bus.base import Bus, BusKind
from imuhal.bus.spy import SpyBus, Transfer, format_transfer
from imuhal.core.clock import SimulatedClock
from imuhal.core.errors import NackError
from imuhal.emulation import EmulatedBus


def _spied() -> tuple[SpyBus, list[Transfer]]:
    inner = EmulatedBus("emul://i2c", BusKind.I2C)
    inner.attach(0x19, TC3Emulator())
    log: list[Transfer] = []
    return SpyBus(inner, log.append, SimulatedClock(5_000_000)), log


def test_a_transaction_passes_through_and_is_recorded() -> None:
    spy, log = _spied()
    assert spy.transfer(0x19, b"\x0f", 1) == b"\x5a"
    assert log == [Transfer(5_000_000, "emul://i2c", 0x19, b"\x0f", b"\x5a", read_len=1)]
    assert format_transfer(log[0]).endswith("emul://i2c @19 W:0f R:5a")


def test_a_failed_transaction_is_recorded_and_still_raises() -> None:
    spy, log = _spied()
    with pytest.raises(NackError):
        spy.transfer(0x18, b"\x0f", 1)
    assert "ERR:NackError" in format_transfer(log[0])


def test_a_uarts_received_bytes_and_baud_changes_are_recorded_as_their_own_lines() -> None:
    inner = EmulatedBus("emul://uart", BusKind.SERIAL)  # nothing attached: a silent line
    log: list[Transfer] = []
    spy = SpyBus(inner, log.append, SimulatedClock(5_000_000))
    spy.set_baudrate(9600)  # type: ignore[attr-defined]
    assert spy.receive(0, 64) == b""
    assert [format_transfer(t).split(None, 1)[1] for t in log] == [
        "emul://uart BAUD 9600", "emul://uart @00 RX(64) R:-"]


class _NoBaudBus(Bus):
    """A bus with no line speed to set (an I2C adapter)."""

    kind = BusKind.I2C

    def _transfer(self, target: int, write: bytes, read_len: int) -> bytes:
        return bytes(read_len)


def test_a_spied_bus_offers_set_baudrate_only_when_the_spied_bus_has_it() -> None:
    spy = SpyBus(_NoBaudBus("i2c"), [].append, SimulatedClock(0))
    assert getattr(spy, "set_baudrate", None) is None  # drivers probe for it this way
