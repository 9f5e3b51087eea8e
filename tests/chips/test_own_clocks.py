"""Chips with clocks of their own (issue 25 item 1): the MAX21100 and the HMC5883L measure at
their output periods divided by 1 + oscillator_error and take the truth of each measurement's
own instant, whenever the host reads; the MS5611, which has no output rate, runs each
conversion the host commands for its typical time divided by 1 + oscillator_error."""

from __future__ import annotations

import math

import numpy as np
import pytest

from imuhal.bus.base import BusKind
from imuhal.core.clock import SimulatedClock
from imuhal.core.samples import Quantity
from imuhal.emulation import EmulatedBus, PhysicalInputs
from imuhal_chips.hmc5883l.decode import data_counts_xyz
from imuhal_chips.hmc5883l.emulator import Hmc5883lEmulator
from imuhal_chips.max2110x.emulator import Max21100Emulator
from imuhal_chips.max2110x.registers import Reg
from imuhal_chips.ms5611.commands import ADC_READ, Measurement, convert_command
from imuhal_chips.ms5611.emulator import MS5611Emulator


def _ramp(t_ns: int) -> float:
    """A true value that changes with time (1 unit a second), so a reading names its
    instant."""
    return t_ns / 1e9


def _max21100(error: float) -> tuple[Max21100Emulator, list[tuple[int, float]]]:
    """Gyro and accelerometer at 250 Hz; the host reads the gyro every 3.1 ms for 0.5 s
    (what each read returns, with when it was read)."""
    clock = SimulatedClock()
    bus = EmulatedBus("spi0", BusKind.SPI)
    chip = bus.attach(0, Max21100Emulator(clock))
    chip.oscillator_error = error
    chip.physics_source = lambda t: chip.set_physics(
        PhysicalInputs(angular_rate_rad_s=(0.0, 0.0, _ramp(t))))
    bus.transfer(0, bytes([Reg.GYRO_CFG2, 0x05]), 0)  # gyro 250 Hz
    bus.transfer(0, bytes([Reg.ACC_CFG1, 0x03]), 0)  # accelerometer 250 Hz
    bus.transfer(0, bytes([Reg.POWER_CFG, 0x7F]), 0)  # both in normal mode
    reads = []
    for _ in range(160):
        clock.sleep(0.0031)
        data = bus.transfer(0, bytes([0x80 | Reg.GYRO_X_H]), 6)
        z = int.from_bytes(data[4:6], "big", signed=True)
        reads.append((clock.now_ns(), z * chip.resolution(Quantity.GYRO)))
    return chip, reads


@pytest.mark.parametrize("error", [-0.02, 0.0, 0.02])
def test_the_max21100_measures_on_its_own_clock(error: float) -> None:
    chip, _ = _max21100(error)
    steps = np.diff(np.asarray(chip.measured_ns))
    assert len(steps) > 100
    assert np.all(np.abs(steps - 4e6 / (1 + error)) <= 1)


def test_a_max21100_reading_is_the_truth_of_its_measurement_instant() -> None:
    chip, reads = _max21100(0.015)
    instants = list(chip.measured_ns)
    resolution = chip.resolution(Quantity.GYRO)
    for read_ns, value in reads[2:]:  # from the first measurement on
        newest = max(t for t in instants if t <= read_ns)
        assert value == pytest.approx(_ramp(newest), abs=resolution / 2 + 1e-12)
    # the truth at the host's read times (up to 3.1 ms later) is off by counts
    assert max(abs(v - _ramp(t)) for t, v in reads) > 2 * resolution


def _hmc(error: float) -> tuple[Hmc5883lEmulator, list[tuple[int, float]]]:
    """75 Hz continuous mode, gain 1090 LSB/G; the host reads X every 9 ms for 1 s."""
    clock = SimulatedClock()
    bus = EmulatedBus("i2c1", BusKind.I2C)
    chip = bus.attach(0x1E, Hmc5883lEmulator(clock))
    chip.oscillator_error = error
    chip.physics_source = lambda t: chip.set_physics(
        PhysicalInputs(magnetic_field_ut=(100.0 * _ramp(t), 0.0, 0.0)))
    bus.transfer(0x1E, bytes([0x00, 0x18, 0x20, 0x00]), 0)
    reads = []
    for _ in range(110):
        clock.sleep(0.009)
        x, _, _ = data_counts_xyz(bus.transfer(0x1E, b"\x03", 6))
        reads.append((clock.now_ns(), x * chip.resolution(Quantity.MAG)))
    return chip, reads


@pytest.mark.parametrize("error", [-0.02, 0.02])
def test_the_hmc5883l_measures_on_its_own_clock_at_the_truth_of_each_instant(
        error: float) -> None:
    chip, reads = _hmc(error)
    instants = list(chip.measured_ns)
    assert np.all(np.abs(np.diff(instants) - 1e9 / 75 / (1 + error)) <= 1)
    resolution = chip.resolution(Quantity.MAG)
    for read_ns, value in reads[2:]:  # from the first measurement on
        newest = max(t for t in instants if t <= read_ns)
        assert value == pytest.approx(100.0 * _ramp(newest), abs=resolution / 2 + 1e-9)


@pytest.mark.parametrize("error", [-0.02, 0.02])
def test_an_hmc5883l_single_measurement_runs_on_its_own_oscillator(error: float) -> None:
    clock = SimulatedClock()
    bus = EmulatedBus("i2c1", BusKind.I2C)
    chip = bus.attach(0x1E, Hmc5883lEmulator(clock))
    chip.oscillator_error = error
    bus.transfer(0x1E, bytes([0x02, 0x01]), 0)  # Mode: single measurement
    start_ns = clock.now_ns()
    clock.sleep(0.007)
    bus.transfer(0x1E, bytes([0x09]), 1)  # status: the measurement is done by now
    assert list(chip.measured_ns) == [start_ns + round(6_000_000 / (1 + error))]


@pytest.mark.parametrize("error", [-0.05, 0.0, 0.05])
def test_an_ms5611_conversion_runs_on_its_own_oscillator(error: float) -> None:
    clock = SimulatedClock()
    chip = MS5611Emulator(clock)
    chip.oscillator_error = error
    chip.bus_transfer(BusKind.I2C, bytes([convert_command(Measurement.D1, 4096)]), 0)
    started = clock.now_ns()
    span = math.floor(8.22e6 / (1 + error))
    clock.sleep((span - 2_000) / 1e9)
    assert chip.converting
    clock.sleep(4_000 / 1e9)
    assert chip.bus_transfer(BusKind.I2C, bytes([ADC_READ]), 3) != bytes(3)
    assert list(chip.measured_ns) == [started + round(8.22e6 / (1 + error))]


def test_an_ms5611_oscillator_beyond_the_datasheets_conversion_times_is_refused() -> None:
    with pytest.raises(ValueError, match="outside the datasheet's conversion times"):
        MS5611Emulator().oscillator_error = 0.12


def test_an_oscillator_error_beyond_ten_percent_is_refused_naming_it() -> None:
    from imuhal.emulation import ChipEmulator

    assert ChipEmulator.checked_oscillator_error(-0.02) == -0.02
    with pytest.raises(ValueError, match=r"oscillator_error 0\.2 is not a clock error"):
        ChipEmulator.checked_oscillator_error(0.2)
