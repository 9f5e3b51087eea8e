"""A bus master's data read that changes nothing in the AK8963 (the MPU-9250's slave 0
repeating ST1..ST2 between the magnetometer's measurements) is answered without being
carried out (``ChipEmulator.idle_answer``, ``EmulatedBus.transfer_at``), with what carrying
it out answers; any read that would change something is carried out."""

from __future__ import annotations

import pytest

from imuhal.bus.base import BusKind
from imuhal.core.clock import SimulatedClock
from imuhal.emulation import EmulatedBus, PhysicalInputs
from imuhal_chips.ak8963.emulator import AK8963Emulator

A = 0x0C
ST1, HXL = b"\x02", b"\x03"
PERIOD_S = 1 / 100  # continuous mode 2


def continuous(first: bytes = ST1) -> tuple[SimulatedClock, EmulatedBus, AK8963Emulator]:
    """An AK8963 in continuous mode 2, 16-bit, its first measurement read out from
    ``first`` to ST2."""
    clock = SimulatedClock()
    bus = EmulatedBus("aux", BusKind.I2C)
    emu = bus.attach(A, AK8963Emulator(clock))
    emu.set_physics(PhysicalInputs(magnetic_field_ut=(21.0, -4.5, 40.0)))
    bus.transfer(A, bytes([0x0A, 0x16]), 0)  # CNTL1: 16-bit, continuous mode 2
    clock.sleep(0.008)  # the first measurement completes 7.2 ms after the write
    bus.transfer(A, first, 10 - first[0])
    return clock, bus, emu


def state(emu: AK8963Emulator) -> tuple:
    return (emu._pointer, emu._st1, emu._st2, bytes(emu._data), emu._protected, emu._held,
            emu._next_ns, emu._cntl1, list(emu.measured_ns))


@pytest.mark.parametrize("first", [ST1, HXL], ids=["from ST1", "from HXL"])
def test_a_repeated_data_read_between_measurements_answers_what_the_read_returns(
        first: bytes) -> None:
    clock, bus, emu = continuous(first)
    clock.sleep(PERIOD_S / 4)
    before = state(emu)
    answer = emu.idle_answer(BusKind.I2C, first, 10 - first[0])
    assert answer is not None
    assert state(emu) == before
    assert bus.transfer(A, first, 10 - first[0]) == answer
    assert state(emu) == before  # the read it stands for changed nothing either
    assert answer[-7:-1] != bytes(6)  # the measured field, not an empty block


def test_no_idle_answer_once_a_measurement_falls_due() -> None:
    clock, _, emu = continuous()
    clock.sleep(PERIOD_S)
    assert emu.idle_answer(BusKind.I2C, ST1, 8) is None


def test_no_idle_answer_while_new_data_waits() -> None:
    clock, bus, emu = continuous()
    clock.sleep(PERIOD_S)
    bus.transfer(A, b"\x00", 1)  # WIA: the measurement completes, DRDY set, pointer moved
    bus.transfer(A, ST1, 1)  # ST1 alone leaves DRDY set; the pointer now at HXL
    bus.transfer(A, b"\x0A", 0)  # the pointer back past ST2
    assert emu._st1 & 0x01
    assert emu.idle_answer(BusKind.I2C, ST1, 8) is None


def test_no_idle_answer_after_a_partial_read_or_for_another_transaction() -> None:
    _, bus, emu = continuous()
    assert emu.idle_answer(BusKind.I2C, ST1, 7) is None  # stops short of ST2
    assert emu.idle_answer(BusKind.I2C, b"\x00", 10) is None  # WIA, INFO first
    assert emu.idle_answer(BusKind.I2C, bytes([0x0A, 0x16]), 1) is None  # writes CNTL1
    bus.transfer(A, HXL, 2)  # X protects the data until ST2 is read
    assert emu.idle_answer(BusKind.I2C, ST1, 8) is None


def test_no_idle_answer_with_the_pointer_elsewhere() -> None:
    # the read moves the pointer past ST2: a pointer standing elsewhere would move
    _, bus, emu = continuous()
    bus.transfer(A, b"\x00", 1)
    assert emu.idle_answer(BusKind.I2C, ST1, 8) is None
