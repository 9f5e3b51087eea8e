"""The BMP280 emulator's own clock (issue 25): in normal mode it completes measurements at
measurement + standby times divided by 1 + oscillator_error, and takes the truth of each
completion instant, whenever the host reads."""

from __future__ import annotations

import numpy as np
import pytest

from imuhal.bus.base import BusKind
from imuhal.core.clock import SimulatedClock
from imuhal_chips.bmp280 import registers as r
from imuhal_chips.bmp280.emulator import BMP280Emulator

# ctrl_meas: osrs_t x1 (001), osrs_p x4 (011), normal mode; config: t_sb 62.5 ms (001)
CTRL_MEAS = 0b001_011_00 | r.MODE_NORMAL
CONFIG = 0b001_000_00
NOMINAL_PERIOD_NS = round((1.0 + 2.0 * 1 + 2.0 * 4 + 0.5 + 62.5) * 1e6)
"""Typical measurement time 1 + 2 x osrs_t + 2 x osrs_p + 0.5 ms (datasheet 3.8.1), plus
t_sb."""


def _run(error: float) -> tuple[BMP280Emulator, list[int]]:
    clock = SimulatedClock()
    chip = BMP280Emulator(clock=clock)
    chip.oscillator_error = error
    pulled: list[int] = []
    chip.physics_source = pulled.append
    chip.bus_transfer(BusKind.I2C, bytes([r.REG_CONFIG, CONFIG, r.REG_CTRL_MEAS, CTRL_MEAS]),
                      0)
    clock.sleep(2.0)  # the host reads only now: every measurement is made meanwhile
    chip.bus_transfer(BusKind.I2C, bytes([r.REG_PRESS_MSB]), 6)
    return chip, pulled


@pytest.mark.parametrize("error", [-0.02, 0.0, 0.02])
def test_normal_mode_measures_on_the_chips_own_clock(error: float) -> None:
    chip, _ = _run(error)
    steps = np.diff(np.asarray(chip.measured_ns))
    assert len(steps) > 20
    assert np.all(np.abs(steps - NOMINAL_PERIOD_NS / (1 + error)) <= 2)


def test_each_measurement_takes_the_truth_of_its_own_instant() -> None:
    chip, pulled = _run(0.015)
    assert pulled == list(chip.measured_ns)
