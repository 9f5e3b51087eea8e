"""A bus master's read that changes nothing in the HMC5883L is answered without being carried
out (``ChipEmulator.idle_answer``, ``EmulatedBus.transfer_at``), with what carrying it out
answers; any read that would change something is carried out."""

from __future__ import annotations

from imuhal.bus.base import BusKind
from imuhal.core.clock import SimulatedClock
from imuhal.emulation import ChipEmulator, EmulatedBus, PhysicalInputs
from imuhal.emulation.faults import BoardFaults, BusErrors
from imuhal_chips.hmc5883l.emulator import Hmc5883lEmulator

A = 0x1E
DATA = b"\x03"
PERIOD_S = 1 / 75


def continuous() -> tuple[SimulatedClock, EmulatedBus, Hmc5883lEmulator]:
    """An HMC5883L in continuous mode at 75 Hz, its first measurement read out whole."""
    clock = SimulatedClock()
    bus = EmulatedBus("aux", BusKind.I2C)
    emu = bus.attach(A, Hmc5883lEmulator(clock))
    emu.set_physics(PhysicalInputs(magnetic_field_ut=(21.0, -4.5, 40.0)))
    bus.transfer(A, bytes([0x00, 0x18, 0x20, 0x00]), 0)
    clock.sleep(0.014)
    bus.transfer(A, DATA, 6)
    return clock, bus, emu


def state(emu: Hmc5883lEmulator) -> tuple:
    return (dict(emu.regs), emu.pointer, bytes(emu.data), emu.locked, set(emu._read_mask),
            emu._pending, emu._next_ns, emu.rdy, emu.measurements, list(emu.measured_ns))


def test_a_repeated_data_read_between_measurements_answers_what_the_read_returns() -> None:
    clock, bus, emu = continuous()
    clock.sleep(PERIOD_S / 4)
    before = state(emu)
    answer = emu.idle_answer(BusKind.I2C, DATA, 6)
    assert answer is not None
    assert state(emu) == before
    assert bus.transfer(A, DATA, 6) == answer
    assert state(emu) == before  # the read it stands for changed nothing either


def test_no_idle_answer_once_a_measurement_falls_due() -> None:
    clock, _, emu = continuous()
    clock.sleep(PERIOD_S)
    assert emu.idle_answer(BusKind.I2C, DATA, 6) is None


def test_no_idle_answer_after_a_partial_read_or_for_another_transaction() -> None:
    _, bus, emu = continuous()
    assert emu.idle_answer(BusKind.I2C, b"\x09", 3) is None  # status and ID: other bytes
    assert emu.idle_answer(BusKind.I2C, DATA, 2) is None
    bus.transfer(A, DATA, 2)  # X locks the data until all six are read
    assert emu.idle_answer(BusKind.I2C, DATA, 6) is None


class Answering(ChipEmulator):
    """A slave that tells an idle answer and logs what is carried out."""

    chip = "answering"

    def __init__(self) -> None:
        super().__init__()
        self.carried: list[bytes] = []

    def idle_answer(self, kind: BusKind, write: bytes, read_len: int) -> bytes | None:
        return b"idle"[:read_len]

    def bus_transfer(self, kind: BusKind, write: bytes, read_len: int) -> bytes:
        self.carried.append(bytes(write))
        return b"real"[:read_len]


def test_a_master_read_takes_the_idle_answer_and_counts_a_transfer() -> None:
    bus = EmulatedBus("aux", BusKind.I2C)
    slave = bus.attach(A, Answering())
    assert bus.transfer_at(5, A, DATA, 4) == b"idle"
    assert (slave.carried, bus.transfers) == ([], 1)
    assert bus.transfer_at(5, A, bytes([0x00, 0x18]), 0) == b""  # a write is carried out
    assert slave.carried == [bytes([0x00, 0x18])]


def test_a_read_is_carried_out_while_a_fault_is_scheduled_on_the_line() -> None:
    clock = SimulatedClock()
    bus = EmulatedBus("aux", BusKind.I2C)
    slave = Answering()
    faults = BoardFaults(clock, {"mag": slave},
                         faults=[BusErrors(device="mag", rate=0.5, start_s=10.0)])
    bus.attach(A, faults.line("mag", slave, bus, A))
    assert bus.transfer_at(5, A, DATA, 4) == b"real"  # before the fault's window too
    assert slave.carried == [DATA]
