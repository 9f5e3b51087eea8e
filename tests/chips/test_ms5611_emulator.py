"""MS5611 emulator: the datasheet's command semantics, on I2C and SPI, and its fault hooks."""

from __future__ import annotations

import pytest

from imuhal.bus.base import BusKind, Link
from imuhal.core.clock import SimulatedClock
from imuhal.core.errors import NackError
from imuhal.emulation import EmulatedBus, PhysicalInputs
from imuhal_chips.ms5611.commands import (
    ADC_READ,
    OSR_TIMING,
    RESET,
    RESET_RELOAD_NS,
    Measurement,
    convert_command,
    prom_read_command,
)
from imuhal_chips.ms5611.conversion import crc4, prom_is_valid
from imuhal_chips.ms5611.emulator import MS5611Emulator
from imuhal_chips.ms5611.emulator_encoding import PromCoefficients, counts_for

DATASHEET_C = (40127, 36924, 23317, 23282, 33464, 28312)
OSR = 4096
TYP_NS = OSR_TIMING[OSR].typ_ns


def setup(kind: BusKind = BusKind.I2C) -> tuple[SimulatedClock, MS5611Emulator, Link]:
    clock = SimulatedClock()
    emulator = MS5611Emulator(clock)
    emulator.set_physics(PhysicalInputs(pressure_pa=95000.0, temperature_degc=15.0))
    bus = EmulatedBus("bus0", kind)
    target = 0x77 if kind is BusKind.I2C else 0
    bus.attach(target, emulator)
    return clock, emulator, bus.link(target)


def adc(link: Link) -> int:
    return int.from_bytes(link.transfer(bytes([ADC_READ]), 3), "big")


def prom(link: Link) -> list[int]:
    return [int.from_bytes(link.transfer(bytes([prom_read_command(n)]), 2), "big")
            for n in range(8)]


def convert(link: Link, measurement: Measurement) -> None:
    link.transfer(bytes([convert_command(measurement, OSR)]))


@pytest.mark.parametrize("kind", [BusKind.I2C, BusKind.SPI])
def test_default_prom_is_crc_valid_with_datasheet_coefficients(kind: BusKind) -> None:
    _, _, link = setup(kind)
    words = prom(link)
    assert prom_is_valid(words)
    assert words[1:7] == list(DATASHEET_C)
    assert words[7] & 0xF == crc4(words)


def test_adc_read_without_conversion_returns_zero() -> None:
    _, _, link = setup()
    assert adc(link) == 0


@pytest.mark.parametrize("kind", [BusKind.I2C, BusKind.SPI])
def test_finished_conversion_returns_encoded_physics_once(kind: BusKind) -> None:
    clock, _, link = setup(kind)
    d1, d2 = counts_for(PromCoefficients(*DATASHEET_C), 95000.0, 15.0)
    convert(link, Measurement.D2)
    clock.sleep_until(TYP_NS)  # the emulator converts in the typical time
    assert adc(link) == d2
    assert adc(link) == 0  # a repeated read returns 0
    convert(link, Measurement.D1)
    clock.sleep_until(2 * TYP_NS)
    assert adc(link) == d1


def test_early_adc_read_returns_zero_and_aborts_the_conversion() -> None:
    clock, emulator, link = setup()
    convert(link, Measurement.D1)
    clock.sleep_until(TYP_NS - 1)
    assert adc(link) == 0
    clock.sleep_until(10 * TYP_NS)
    assert adc(link) == 0  # the aborted conversion never delivers
    assert emulator.aborted_conversions == 1


def test_physics_is_captured_at_conversion_start() -> None:
    clock, emulator, link = setup()
    d1_start, _ = counts_for(PromCoefficients(*DATASHEET_C), 95000.0, 15.0)
    convert(link, Measurement.D1)
    emulator.set_physics(PhysicalInputs(pressure_pa=80000.0, temperature_degc=15.0))
    clock.sleep_until(TYP_NS)
    assert adc(link) == d1_start


def test_new_conversion_during_one_gives_a_wrong_result() -> None:
    clock, _, link = setup()
    d1, _ = counts_for(PromCoefficients(*DATASHEET_C), 95000.0, 15.0)
    convert(link, Measurement.D1)
    clock.sleep_until(TYP_NS // 2)
    convert(link, Measurement.D1)
    clock.sleep_until(3 * TYP_NS)
    result = adc(link)
    assert result != 0 and result != d1


def test_reset_aborts_conversion_and_reload_takes_2_8_ms() -> None:
    clock, emulator, link = setup()
    convert(link, Measurement.D1)
    link.transfer(bytes([RESET]))
    clock.sleep_until(RESET_RELOAD_NS - 1)
    assert emulator.reloading
    assert prom(link) == [0] * 8  # no PROM output while reloading
    convert(link, Measurement.D2)  # ignored during the reload
    clock.sleep_until(RESET_RELOAD_NS)
    assert not emulator.reloading
    assert prom_is_valid(prom(link))
    clock.sleep_until(RESET_RELOAD_NS + 2 * TYP_NS)
    assert adc(link) == 0  # neither the aborted nor the ignored conversion delivers


def test_silent_reset_loses_the_running_conversion() -> None:
    clock, emulator, link = setup()
    convert(link, Measurement.D1)
    clock.sleep_until(TYP_NS // 2)
    emulator.silent_reset()
    clock.sleep_until(2 * TYP_NS)
    assert adc(link) == 0


def test_i2c_command_and_read_in_separate_transactions() -> None:
    _, _, link = setup()
    link.transfer(bytes([prom_read_command(1)]))
    assert int.from_bytes(link.transfer(b"", 2), "big") == DATASHEET_C[0]


def test_corrupt_prom_breaks_crc() -> None:
    _, emulator, link = setup()
    emulator.corrupt_prom(3, 5)
    words = prom(link)
    assert words[3] == DATASHEET_C[2] ^ (1 << 5)
    assert not prom_is_valid(words)


@pytest.mark.parametrize("fill", [0x0000, 0xFFFF])
def test_blank_proms(fill: int) -> None:
    _, emulator, link = setup()
    emulator.fill_prom(fill)
    assert prom(link) == [fill] * 8


def test_absent_chip_nacks() -> None:
    _, emulator, link = setup()
    emulator.absent = True
    with pytest.raises(NackError):
        prom(link)


def test_custom_prom_words() -> None:
    words = [0x0001, 1, 2, 3, 4, 5, 6, 0x1230]
    clock = SimulatedClock()
    bus = EmulatedBus("bus0", BusKind.SPI)
    bus.attach(0, MS5611Emulator(clock, prom_words=words))
    assert prom(bus.link(0)) == words
