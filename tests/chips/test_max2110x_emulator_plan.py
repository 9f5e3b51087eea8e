"""The MAX2110x emulator's fast paths give what its one-value paths give: counts encoded for
a whole plan of inputs at once, the register image kept up to date in place, and a FIFO read
popped at once."""

from __future__ import annotations

import numpy as np
import pytest

from imuhal.bus.base import BusKind
from imuhal.core.clock import SimulatedClock
from imuhal.emulation import EmulatedBus, PhysicalInputs, PlannedInputs
from imuhal_chips.max2110x.emulator import (
    Max21100Emulator,
    Max21105Emulator,
    _encode,
    _encode_rows,
)
from imuhal_chips.max2110x.emulator_fifo import MAX21100_FIFO, Max2110xFifo

PER_COUNT = 1.0 / 7500.0 * 9.80665


def test_rows_encode_each_value_as_one_value_encodes() -> None:
    halves = np.array([0.5, 1.5, 2.5, -0.5, -1.5, -2.5, 29999.5, -29999.5]) * PER_COUNT
    odd = [0.0, -0.0, 1e-300, -1e-300, 1e6, -1e6, np.inf, -np.inf, np.nan, 3.0000001]
    rng = np.random.default_rng(7)
    values = np.concatenate([halves, odd, rng.normal(0.0, 40.0, 3 * 200)])
    values = values[: len(values) // 3 * 3].reshape(-1, 3)
    encoded = _encode_rows(values, PER_COUNT, 30000)
    assert encoded is not None
    assert encoded.tolist() == [[_encode(float(v), PER_COUNT, 30000) for v in row]
                                for row in values]
    assert all(type(c) is int for row in encoded.tolist() for c in row)


def test_rows_are_left_to_the_one_value_path_where_a_quotient_overflows() -> None:
    # round() of an infinite quotient raises; the whole plan then goes value by value
    assert _encode_rows(np.array([[1e308, 0.0, 0.0]]), 1e-10, 30000) is None


def _plan(n: int, seed: int) -> PlannedInputs:
    rng = np.random.default_rng(seed)
    return PlannedInputs(rng.normal(0.0, 30.0, (n, 3)), rng.normal(0.0, 3.0, (n, 3)),
                         rng.normal(0.0, 50.0, (n, 3)), rng.normal(9e4, 50.0, n),
                         rng.normal(30.0, 10.0, n), rng.normal(0.0, 5.0, (n, 3)),
                         rng.normal(0.0, 5.0, (n, 3)))


def _chip(cls: type[Max21100Emulator]) -> tuple[SimulatedClock, EmulatedBus, Max21100Emulator]:
    clock = SimulatedClock()
    bus = EmulatedBus("spi0", BusKind.SPI)
    emu = bus.attach(0, cls(clock))
    bus.transfer(0, bytes([0x00, 0x7F]), 0)  # gyro and accelerometer on
    bus.transfer(0, bytes([0x01, 0x05]), 0)  # gyro +/-500 dps
    return clock, bus, emu


@pytest.mark.parametrize("cls", [Max21100Emulator, Max21105Emulator])
def test_a_planned_row_latches_the_bytes_of_the_same_inputs_handed_over(cls) -> None:
    plan = _plan(40, 3)
    planned_clock, planned_bus, planned = _chip(cls)
    handed_clock, handed_bus, handed = _chip(cls)
    for i in range(len(plan)):
        planned.set_planned(plan, i)
        handed.set_physics(plan.row(i))
        for clock in (planned_clock, handed_clock):
            clock.sleep(0.0025)
        burst = bytes([0x80 | 0x23])
        assert planned_bus.transfer(0, burst, 21) == handed_bus.transfer(0, burst, 21)
        assert planned.physics == handed.physics  # the row, when asked for


def test_a_planned_row_reads_as_its_inputs_while_frozen_chips_keep_theirs() -> None:
    plan = _plan(3, 5)
    _, _, emu = _chip(Max21100Emulator)
    emu.set_planned(plan, 1)
    assert emu.physics == plan.row(1)
    emu.frozen = True
    emu.set_planned(plan, 2)
    assert emu.physics == plan.row(1)


def test_a_burst_after_new_latches_reads_what_each_register_alone_reads() -> None:
    # the image the bursts are served from is written in place at each latch
    clock, bus, emu = _chip(Max21100Emulator)
    rng = np.random.default_rng(11)
    for little_endian in (False, True, False):
        bus.transfer(0, bytes([0x16, 0x02 if little_endian else 0x00]), 0)
        for _ in range(5):
            emu.set_physics(PhysicalInputs(
                angular_rate_rad_s=tuple(rng.normal(0.0, 2.0, 3).tolist()),
                specific_force_m_s2=tuple(rng.normal(0.0, 20.0, 3).tolist()),
                temperature_degc=float(rng.normal(30.0, 5.0))))
            clock.sleep(0.003)
            emu._advance()
            single = bytes(emu._read(r) for r in range(0x23, 0x3C))
            assert bus.transfer(0, bytes([0x80 | 0x23]), 0x3C - 0x23) == single
            assert bus.transfer(0, bytes([0x80 | 0x2A]), 6) == single[0x2A - 0x23:0x30 - 0x23]


@pytest.mark.parametrize("count", [1, 6, 13, 40])
def test_popping_many_fifo_bytes_is_popping_each(count) -> None:
    fifos = [Max2110xFifo(MAX21100_FIFO) for _ in range(2)]
    for fifo in fifos:
        fifo.write(MAX21100_FIFO.cfg, 0x43)  # normal mode, gyro and accelerometer stored
        for k in range(2):
            fifo.push(bytes(range(12 * k, 12 * k + 12)))
    many, each = fifos
    assert many.pop_many(count) == bytes(each.pop() for _ in range(count))
    assert many.status(6) == each.status(6)  # read_empty set alike past the end
    assert many.words() == each.words()
