"""I2C reads without a register byte continue from the register pointer, on every emulator
with a register file.

Drivers that cannot issue a repeated start (and Linux ``i2c_smbus`` fallbacks) write the
register in one transaction and read in the next; a burst read auto-increments the pointer,
so a following read without a register byte continues where the last one stopped. Each case
reads static registers (identity, trimming, configuration) three ways and compares: one burst,
and the same bytes split over a pointer write and two bare reads.
"""

from __future__ import annotations

from collections.abc import Callable

import pytest

from imuhal.bus.base import BusKind, Link
from imuhal.core.clock import SimulatedClock
from imuhal.emulation import ChipEmulator, EmulatedBus
from imuhal_chips.ak8963.emulator import AK8963Emulator
from imuhal_chips.bmp280.emulator import BMP280Emulator
from imuhal_chips.hmc5883l.emulator import Hmc5883lEmulator
from imuhal_chips.max2110x.emulator import Max21100Emulator, Max21105Emulator
from imuhal_chips.mpu9250.emulator import MPU9250Emulator

CASES: dict[str, tuple[Callable[[SimulatedClock], ChipEmulator], int, bytes, int, int]] = {
    # name: (emulator, identity register, its bytes from the datasheet,
    #        start and length of a split read over registers that are not all equal)
    # (PWR_MGMT_1 reads 0x01 after power-on, PWR_MGMT_2 0x00; FIFO_R_W at 0x74 does not
    # advance the pointer: a burst from it pops the FIFO)
    "mpu9250": (lambda c: MPU9250Emulator(c), 0x75, bytes([0x71]), 0x6B, 1),
    "max21105": (lambda c: Max21105Emulator(c), 0x20, bytes([0xB4]), 0x20, 1),
    "max21100": (lambda c: Max21100Emulator(c), 0x20, bytes([0xB2]), 0x20, 1),
    "bmp280": (lambda c: BMP280Emulator(c), 0x88, bytes([0x70, 0x6B, 0x43, 0x67]), 0x88, 6),
    "ak8963": (lambda c: AK8963Emulator(c), 0x00, bytes([0x48]), 0x00, 1),
    "hmc5883l": (lambda c: Hmc5883lEmulator(c), 0x0A, b"H43", 0x0A, 1),
}


def _link(name: str) -> Link:
    make = CASES[name][0]
    bus = EmulatedBus("bus", BusKind.I2C)
    bus.attach(0x42, make(SimulatedClock()))
    return bus.link(0x42)


@pytest.mark.parametrize("name", sorted(CASES))
def test_a_bare_read_returns_the_register_written_before(name: str) -> None:
    _, register, identity, _, _ = CASES[name]
    link = _link(name)
    link.transfer(bytes([register]))
    assert link.transfer(b"", len(identity)) == identity


@pytest.mark.parametrize("name", sorted(CASES))
def test_a_bare_read_continues_where_the_last_read_stopped(name: str) -> None:
    _, _, _, register, length = CASES[name]
    link = _link(name)
    burst = link.transfer(bytes([register]), 2 * length)
    assert burst[:length] != burst[length:], "the split must be visible"
    first = link.transfer(bytes([register]), length)
    rest = link.transfer(b"", length)
    assert first + rest == burst
