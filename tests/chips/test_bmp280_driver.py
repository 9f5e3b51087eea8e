"""BMP280 driver against the register-level emulator on I2C and SPI, on one simulated clock."""

from __future__ import annotations

import random
from typing import Any

import pytest
from tests.support.driving import poll_count

from imuhal.bus.base import BusKind
from imuhal.core.clock import SimulatedClock
from imuhal.core.errors import BusError, DeviceNotFoundError
from imuhal.core.samples import PressureSample, Quantity, SampleFlag, TemperatureSample
from imuhal.emulation import EmulatedBus, PhysicalInputs
from imuhal_chips.bmp280 import registers as r
from imuhal_chips.bmp280.driver import BMP280Driver, BMP280Settings
from imuhal_chips.bmp280.emulator import BMP280Emulator
from imuhal_chips.bmp280.error_spec import BMP280_ERROR_SPEC

ADDRESS = 0x76
FORMULAS_AGREE_PA = 0.5
"""The driver compensates with the datasheet's 64-bit integer formula (integer t_fine), the
emulator encodes with the inverse of its double-precision formula: over the operating range
the two differ by up to 0.45 Pa, on top of one ADC step."""


def rig(kind: BusKind = BusKind.I2C, **settings: Any) -> tuple[
        SimulatedClock, EmulatedBus, BMP280Emulator, BMP280Driver]:
    clock = SimulatedClock()
    bus = EmulatedBus("bus0", kind)
    emu = bus.attach(ADDRESS, BMP280Emulator(clock))
    driver = BMP280Driver(bus.link(ADDRESS), settings, device="baro", clock=clock)
    return clock, bus, emu, driver


def run(clock: SimulatedClock, driver: BMP280Driver, n_samples: int,
        start: int | None = None) -> list[Any]:
    """Poll on the shared clock until ``n_samples`` samples (both channels) came out."""
    return poll_count(driver, clock, n_samples, start=start)


def pressures(samples: list[Any]) -> list[PressureSample]:
    return [s for s in samples if isinstance(s, PressureSample)]


def test_worked_example_at_register_level() -> None:
    """The datasheet trim and data bytes, read through the bus, compensate to its numbers."""
    clock, _bus, emu, driver = rig()
    driver.probe()
    driver.configure()
    emu._data[:] = bytes([0x65, 0x5A, 0xC0, 0x7E, 0xED, 0x00])  # what the chip latched
    emu.stuck_data_ready = True  # keep it: no new measurement overwrites it
    samples = driver.poll(clock.now_ns()).samples
    p, t = samples
    assert isinstance(p, PressureSample) and isinstance(t, TemperatureSample)
    assert p.pressure_pa == 25767233 / 256
    assert t.temperature_degc == 25.08


@pytest.mark.parametrize("kind", [BusKind.I2C, BusKind.SPI])
@pytest.mark.parametrize("mode", ["normal", "forced"])
def test_reads_the_true_pressure_and_temperature(kind: BusKind, mode: str) -> None:
    clock, _bus, emu, driver = rig(kind, mode=mode)
    emu.set_physics(PhysicalInputs(pressure_pa=95_432.1, temperature_degc=17.3))
    driver.probe()
    driver.configure()
    samples = run(clock, driver, 6)
    p = pressures(samples)[-1]
    t = [s for s in samples if isinstance(s, TemperatureSample)][-1]
    assert p.valid and t.valid
    assert abs(p.pressure_pa - 95_432.1) <= emu.resolution(Quantity.PRESSURE) + FORMULAS_AGREE_PA
    assert abs(t.temperature_degc - 17.3) <= emu.resolution(Quantity.TEMPERATURE)


SWEEP = (
    [{"pressure_oversampling": v} for v in (1, 2, 4, 8, 16)]
    + [{"temperature_oversampling": v, "odr_hz": 10.0} for v in (1, 2, 4, 8, 16)]
    + [{"iir_coefficient": v} for v in (0, 2, 4, 8, 16)]
    + [{"standby_ms": v} for v in (0.5, 62.5, 125.0, 250.0)]
    + [{"mode": "forced", "odr_hz": 10.0}, {"mode": "normal", "odr_hz": 1.0}]
)


@pytest.mark.parametrize("setting", SWEEP, ids=lambda s: "-".join(f"{k}={v}" for k, v in
                                                                  s.items()))
def test_every_setting_reads_within_one_lsb(setting: dict[str, Any]) -> None:
    clock, _bus, emu, driver = rig(**setting)
    truth_p, truth_t = 0.63 * emu.full_scale(Quantity.PRESSURE) + 12.34, 31.27
    emu.set_physics(PhysicalInputs(pressure_pa=truth_p, temperature_degc=truth_t))
    driver.probe()
    driver.configure()
    samples = run(clock, driver, 4)
    p = pressures(samples)[-1]
    t = [s for s in samples if isinstance(s, TemperatureSample)][-1]
    assert abs(p.pressure_pa - truth_p) <= emu.resolution(Quantity.PRESSURE) + FORMULAS_AGREE_PA
    assert abs(t.temperature_degc - truth_t) <= emu.resolution(Quantity.TEMPERATURE)


def test_configure_programs_the_table_codes() -> None:
    _clock, _bus, emu, driver = rig(pressure_oversampling=16, temperature_oversampling=2,
                                  iir_coefficient=16, standby_ms=62.5)
    driver.probe()
    driver.configure()
    # osrs_t x2 = 010, osrs_p x16 = 101, normal = 11; t_sb 62.5 = 001, filter 16 = 100
    assert emu._ctrl == 0b010_101_11
    assert emu._config == 0b001_100_00


def test_settings_reject_values_listing_the_allowed_ones() -> None:
    with pytest.raises(ValueError, match="1, 2, 4, 8 or 16"):
        BMP280Settings(pressure_oversampling=3)
    with pytest.raises(ValueError, match=r"0\.5, 62\.5, 125"):
        BMP280Settings(standby_ms=100)
    with pytest.raises(ValueError, match="at most"):
        BMP280Settings(mode="forced", odr_hz=200, pressure_oversampling=16)


def test_forced_mode_returns_to_sleep_after_one_measurement() -> None:
    clock, bus, _emu, driver = rig(mode="forced", odr_hz=5.0)
    driver.probe()
    driver.configure()
    t = driver.start(clock.now_ns())
    clock.sleep_until(t)
    t = driver.poll(clock.now_ns()).next_poll_ns  # triggers

    def status_ctrl() -> bytes:
        return bus.transfer(ADDRESS, bytes([r.REG_STATUS]), 2)

    status, ctrl = status_ctrl()
    assert status & r.STATUS_MEASURING and ctrl & r.MODE_MASK == r.MODE_FORCED
    clock.sleep_until(t)
    status, ctrl = status_ctrl()
    assert not status & r.STATUS_MEASURING and ctrl & r.MODE_MASK == r.MODE_SLEEP


def test_pressure_at_the_adc_limit_is_saturated() -> None:
    clock, _bus, emu, driver = rig(iir_coefficient=0)
    # Beyond what the 20-bit ADC can encode with this trim (adc_P = 0 at ~171.7 kPa).
    emu.set_physics(PhysicalInputs(pressure_pa=200_000.0, temperature_degc=20.0))
    driver.probe()
    driver.configure()
    p = pressures(run(clock, driver, 2))[-1]
    assert SampleFlag.SATURATED in p.flags
    assert SampleFlag.OUT_OF_RANGE in p.flags


def test_wrong_identity_names_bme280() -> None:
    _clock, _bus, emu, driver = rig()
    emu.chip_id = 0x60
    with pytest.raises(DeviceNotFoundError) as err:
        driver.probe()
    assert err.value.found == "0x60" and "BME280" in err.value.hint
    assert err.value.bus == "bus0" and err.value.address == ADDRESS and "0x58" in err.value.expected


def test_absent_chip_raises_device_not_found() -> None:
    _clock, _bus, emu, driver = rig()
    emu.absent = True
    with pytest.raises(DeviceNotFoundError, match="NACK"):
        driver.probe()


def test_a_forced_conversion_a_hang_held_completes_after_the_hang_not_inside_it() -> None:
    """A hang 5 ms into a forced conversion (typical 19.5 ms at x8/x1) holds it: every
    status read during the hang says ``measuring``, so the conversion cannot be dated
    inside it. When the hang ends the engine resumes: the 14.5 ms the conversion had left
    come after the end, and the chip records one measurement then (before, it completed
    at its own instant, inside the hang, 12 ms before a read that found it running)."""
    clock, bus, emu, driver = rig(mode="forced", odr_hz=5.0)
    driver.probe()
    driver.configure()  # x8 pressure, x1 temperature, asleep
    bus.transfer(ADDRESS, bytes([r.REG_CTRL_MEAS, r.ctrl_meas_value(1, 8, r.MODE_FORCED)]), 0)
    clock.sleep(0.005)
    emu.stuck_data_ready = True
    clock.sleep(0.026)
    assert bus.transfer(ADDRESS, bytes([r.REG_STATUS]), 1)[0] & r.STATUS_MEASURING
    emu.stuck_data_ready = False
    ended = clock.now_ns()
    clock.sleep(0.030)
    assert not bus.transfer(ADDRESS, bytes([r.REG_STATUS]), 1)[0] & r.STATUS_MEASURING
    assert list(emu.measured_ns)[-1:] == [ended + 19_500_000 - 5_000_000]


def test_stuck_conversion_in_forced_mode_is_stale_and_recover_works() -> None:
    clock, _bus, emu, driver = rig(mode="forced", odr_hz=10.0)
    driver.probe()
    driver.configure()
    emu.stuck_data_ready = True
    samples = run(clock, driver, 2)
    assert all(s.flags == SampleFlag.STALE for s in samples)
    emu.stuck_data_ready = False
    start = driver.recover(clock.now_ns())
    assert all(s.valid for s in run(clock, driver, 2, start))


def test_silent_reset_is_detected_and_repaired() -> None:
    clock, _bus, emu, driver = rig()
    emu.set_physics(PhysicalInputs(pressure_pa=90_000.0, temperature_degc=20.0))
    driver.probe()
    driver.configure()
    t = driver.start(clock.now_ns())
    run(clock, driver, 4, t)
    emu.silent_reset()
    samples = run(clock, driver, 6)
    assert driver.health.resets_detected == 1
    assert driver.health.reconfigurations == 1
    assert samples and all(s.valid for s in samples)
    assert abs(pressures(samples)[-1].pressure_pa - 90_000.0) <= emu.resolution(
        Quantity.PRESSURE)


def test_bus_error_propagates_and_recover_restores_sampling() -> None:
    clock, bus, _emu, driver = rig()
    driver.probe()
    driver.configure()
    t = driver.start(clock.now_ns())
    clock.sleep_until(t)
    bus.fail_transfers({1})
    with pytest.raises(BusError):
        driver.poll(clock.now_ns())
    start = driver.recover(clock.now_ns())
    samples = run(clock, driver, 2, start)
    assert samples and all(s.valid for s in samples) and driver.health.reconfigurations == 1


def test_spi_reads_set_bit7_and_writes_are_address_data_pairs_with_bit7_clear() -> None:
    clock = SimulatedClock()
    seen: list[bytes] = []

    class Spy(BMP280Emulator):
        def bus_transfer(self, kind: BusKind, write: bytes, read_len: int) -> bytes:
            seen.append(write)
            return super().bus_transfer(kind, write, read_len)

    bus = EmulatedBus("spi0", BusKind.SPI)
    bus.attach(0, Spy(clock))
    driver = BMP280Driver(bus.link(0), {}, device="baro", clock=clock)
    driver.probe()
    driver.configure()
    assert seen[0] == bytes([0xD0])
    assert bytes([0x60, 0xB6]) in seen  # reset: 0xE0 with bit 7 cleared
    writes = [w for w in seen if len(w) >= 2]
    assert all(w[i] & 0x80 == 0 for w in writes for i in range(0, len(w), 2))
    assert driver.trim is not None and driver.trim.T1 == 27504  # 24-byte burst read over SPI


def _outputs(clock: SimulatedClock, driver: BMP280Driver, n: int,
             t: int) -> tuple[list[PressureSample], int]:
    """Poll from ``t`` until ``n`` pressure outputs came; returns them and the next poll."""
    got: list[PressureSample] = []
    while len(got) < n:
        clock.sleep_until(t)
        result = driver.poll(clock.now_ns())
        got += pressures(result.samples)
        t = result.next_poll_ns
    return got, t


@pytest.mark.parametrize(("coefficient", "samples_to_75_percent"),
                         [(2, 2), (4, 5), (8, 11), (16, 22)])
def test_the_emulated_iir_filter_follows_a_step_as_datasheet_table_6_says(
        coefficient: int, samples_to_75_percent: int) -> None:
    """Datasheet 3.4.3, table 6: samples to reach >= 75 % of a step response."""
    clock, _bus, emu, driver = rig(iir_coefficient=coefficient)
    emu.set_physics(PhysicalInputs(pressure_pa=95_000.0, temperature_degc=20.0))
    driver.probe()
    driver.configure()
    before, t = _outputs(clock, driver, 4, driver.start(clock.now_ns()))
    emu.set_physics(PhysicalInputs(pressure_pa=96_000.0, temperature_degc=20.0))
    after, _ = _outputs(clock, driver, 30, t)
    assert before[-1].pressure_pa == pytest.approx(95_000.0, abs=1.0)
    # coefficient 2 reaches exactly 75 % at its second output: 1 Pa (0.1 %) for the rounding
    reached = [s.pressure_pa >= 95_749.0 for s in after]
    assert reached.index(True) + 1 == samples_to_75_percent


def test_a_measurement_at_the_adc_rail_hidden_by_the_iir_filter_is_flagged() -> None:
    """Issue 26 item 1: the filtered output of a -200 kPa world is in range (a quarter of the
    way to the rail at coefficient 4); the driver undoes the filter, flags it SATURATED and
    flags the 49 outputs the filter can still carry it FILTER_SETTLING."""
    clock, _bus, emu, driver = rig(iir_coefficient=4)
    emu.set_physics(PhysicalInputs(pressure_pa=95_000.0, temperature_degc=20.0))
    driver.probe()
    driver.configure()
    _, t = _outputs(clock, driver, 10, driver.start(clock.now_ns()))
    emu.set_physics(PhysicalInputs(pressure_pa=-200_000.0, temperature_degc=20.0))
    wild, t = _outputs(clock, driver, 1, t)
    emu.set_physics(PhysicalInputs(pressure_pa=95_000.0, temperature_degc=20.0))
    after, _ = _outputs(clock, driver, 60, t)
    assert wild[0].flags == SampleFlag.SATURATED
    assert 30_000.0 <= wild[0].pressure_pa <= 110_000.0  # the output alone looks fine
    assert [s.flags for s in after[:49]] == [SampleFlag.FILTER_SETTLING] * 49
    assert all(s.valid and abs(s.pressure_pa - 95_000.0) < 1.0 for s in after[49:])


def _noisy_outputs(n: int, *, frozen_after: int | None = None, quiet: float = 1.0,
                   **settings: Any) -> tuple[BMP280Driver, list[tuple[PressureSample, bytes]]]:
    """``n`` pressure outputs of a chip at rest whose inputs carry ``quiet`` times the
    datasheet's Gaussian noise (the simulator's error spec; seeded), its conversions hung
    from output ``frozen_after`` on; each with the six data bytes the chip held then (read
    on its bus face, as a logic analyser would see them)."""
    clock, _bus, emu, driver = rig(**settings)
    rng = random.Random(7)
    noise_pa = quiet * BMP280_ERROR_SPEC["pressure"]["noise_std"]
    noise_degc = quiet * BMP280_ERROR_SPEC["temperature"]["noise_std"]
    driver.probe()
    driver.configure()
    got: list[tuple[PressureSample, bytes]] = []
    t = driver.start(clock.now_ns())
    while len(got) < n:
        emu.frozen = frozen_after is not None and len(got) >= frozen_after
        emu.set_physics(PhysicalInputs(pressure_pa=95_000.3 + rng.gauss(0.0, noise_pa),
                                       temperature_degc=20.0 + rng.gauss(0.0, noise_degc)))
        clock.sleep_until(t)
        result = driver.poll(clock.now_ns())
        words = emu.bus_transfer(BusKind.I2C, bytes([r.REG_PRESS_MSB]), 6)
        got += [(p, words) for p in pressures(result.samples)]
        t = result.next_poll_ns
    return driver, got


def _first_frozen(got: list[tuple[PressureSample, bytes]]) -> int:
    return next(i for i, (p, _) in enumerate(got) if p.flags & SampleFlag.FROZEN)


def _identical_before(got: list[tuple[PressureSample, bytes]], index: int) -> int:
    """How many outputs before ``index`` held the same data bytes as the one just before."""
    run = 0
    while run < index and got[index - 1 - run][1] == got[index - 1][1]:
        run += 1
    return run


def test_a_chip_with_the_datasheets_noise_learns_a_short_frozen_window() -> None:
    """Filtered 20-bit words at the datasheet's noise seldom repeat: after learning, the
    window is well under the fixed 41 at coefficient 4, and a healthy chip is never flagged
    over 3,000 outputs."""
    driver, got = _noisy_outputs(3000, iir_coefficient=4)
    assert driver.frozen_window() <= 14
    assert not any(p.flags & SampleFlag.FROZEN for p, _ in got)


def test_a_chip_quieter_than_one_lsb_keeps_the_fixed_frozen_window() -> None:
    """A part whose noise moves its filtered word by under one LSB (the conformance sweep's
    dithered chip) repeats most outputs; the learned window stays at the fixed ceiling."""
    driver, _ = _noisy_outputs(150, quiet=0.02, iir_coefficient=4)
    assert driver.frozen_window() == 41


def test_a_frozen_chip_is_flagged_at_the_learned_window() -> None:
    driver, got = _noisy_outputs(300, frozen_after=200, iir_coefficient=4)
    first = _first_frozen(got)
    assert first > 200
    # the window's first output is the one after window - 1 identical ones
    assert _identical_before(got, first) == driver.frozen_window() - 1
    assert all(p.flags & SampleFlag.FROZEN for p, _ in got[first:])


def test_a_chip_frozen_while_the_driver_learns_keeps_the_fixed_window() -> None:
    driver, got = _noisy_outputs(150, frozen_after=30, iir_coefficient=4)
    assert driver.frozen_window() == 41
    assert _identical_before(got, _first_frozen(got)) == 40
