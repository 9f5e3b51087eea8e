"""The emulated bus routes transactions to chip emulators and injects faults."""

from __future__ import annotations

import pytest
from tests.support.testchip import TC3Emulator

from imuhal.bus.base import BusKind
from imuhal.core.errors import BusError, NackError
from imuhal.emulation import EmulatedBus


def test_transfers_reach_the_emulator_at_that_address() -> None:
    bus = EmulatedBus("emul://i2c", BusKind.I2C)
    bus.attach(0x19, TC3Emulator())
    assert bus.transfer(0x19, b"\x0f", 1) == b"\x5a"


def test_an_empty_address_does_not_acknowledge() -> None:
    bus = EmulatedBus("emul://i2c", BusKind.I2C)
    with pytest.raises(NackError, match="0x19"):
        bus.transfer(0x19, b"\x0f", 1)


def test_an_absent_chip_does_not_acknowledge() -> None:
    bus = EmulatedBus("emul://i2c", BusKind.I2C)
    bus.attach(0x19, TC3Emulator()).absent = True
    with pytest.raises(NackError):
        bus.transfer(0x19, b"\x0f", 1)


def test_an_injected_failure_hits_exactly_the_chosen_transfer() -> None:
    bus = EmulatedBus("emul://i2c", BusKind.I2C)
    bus.attach(0x19, TC3Emulator())
    bus.fail_transfers({2})
    bus.transfer(0x19, b"\x0f", 1)
    with pytest.raises(BusError, match="injected"):
        bus.transfer(0x19, b"\x0f", 1)
    assert bus.transfer(0x19, b"\x0f", 1) == b"\x5a"


def test_two_emulators_cannot_share_an_address() -> None:
    bus = EmulatedBus("emul://i2c", BusKind.I2C)
    bus.attach(0x19, TC3Emulator())
    with pytest.raises(ValueError, match="already"):
        bus.attach(0x19, TC3Emulator())
