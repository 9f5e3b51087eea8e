"""MS5611 driver end to end on an emulated bus: probe, sample timing and accuracy, errors."""

from __future__ import annotations

import itertools
import random

import pytest
from pydantic import ValidationError
from tests.support.dither import Dither

from imuhal.bus.base import BusKind
from imuhal.core.clock import SimulatedClock
from imuhal.core.errors import BusError, DeviceNotFoundError
from imuhal.core.samples import PressureSample, Sample, SampleFlag, TemperatureSample
from imuhal.emulation import EmulatedBus, PhysicalInputs
from imuhal.plugins.manager import load_registry
from imuhal_chips.ms5611.commands import Measurement
from imuhal_chips.ms5611.conversion import crc4
from imuhal_chips.ms5611.driver import MS5611Driver, MS5611Settings
from imuhal_chips.ms5611.emulator import MS5611Emulator

# The chip reports integer Pa and 0.01 degC; the emulator encodes to the nearest of those,
# so a driver that decodes correctly is within half a step (plus float noise) of the truth.
P_TOL_PA = 1.0
T_TOL_DEGC = 0.02

TARGETS = {BusKind.I2C: 0x77, BusKind.SPI: 0}


class Rig:
    """A driver and its emulator on one bus, driven on a simulated clock."""

    def __init__(self, kind: BusKind = BusKind.I2C, **settings: object) -> None:
        self.clock = SimulatedClock()
        self.emulator = MS5611Emulator(self.clock)
        self.bus = EmulatedBus(f"{kind.value}-test", kind)
        self.target = TARGETS[kind]
        self.bus.attach(self.target, self.emulator)
        self.driver = MS5611Driver(
            self.bus.link(self.target), MS5611Settings(**settings), device="baro",
            clock=self.clock,
        )
        self.next_ns = 0
        # the pressure moved by up to half a 1 Pa step up or down, as the chip's own noise
        # would (tests/support/dither.py): D1 resolves about 0.02 Pa, so it takes many
        # values and never repeats like a hung converter's; readings stay within P_TOL_PA
        self.dither = Dither(self.emulator, seed=5611, amplitude=0.5 + 1e-6, spread=0.9)

    def physics(self, pressure_pa: float, temperature_degc: float) -> None:
        self.emulator.set_physics(
            PhysicalInputs(pressure_pa=pressure_pa, temperature_degc=temperature_degc)
        )

    def begin(self) -> None:
        self.driver.probe()
        self.driver.configure()
        self.next_ns = self.driver.start(self.clock.now_ns())

    def run_until(self, end_ns: int) -> list[Sample]:
        """Poll at exactly the times the driver asks for, until the clock passes ``end_ns``."""
        samples: list[Sample] = []
        while self.next_ns <= end_ns:
            self.clock.sleep_until(self.next_ns)
            self.dither()
            result = self.driver.poll(self.clock.now_ns())
            assert result.next_poll_ns >= self.clock.now_ns()
            samples += result.samples
            self.next_ns = result.next_poll_ns
        return samples


def pressures(samples: list[Sample]) -> list[PressureSample]:
    return [s for s in samples if isinstance(s, PressureSample)]


def temperatures(samples: list[Sample]) -> list[TemperatureSample]:
    return [s for s in samples if isinstance(s, TemperatureSample)]


@pytest.mark.parametrize("kind", [BusKind.I2C, BusKind.SPI])
def test_samples_track_physics_at_odr_hz(kind: BusKind) -> None:
    rig = Rig(kind)  # defaults: OSR 4096/4096, 50 Hz, temperature every sample
    rig.physics(95123.4, 23.456)
    rig.begin()
    samples = rig.run_until(1_000_000_000)
    p, t = pressures(samples), temperatures(samples)
    assert 49 <= len(p) <= 50 and len(t) == len(p)
    assert all(s.valid for s in samples)
    assert all(abs(s.pressure_pa - 95123.4) <= P_TOL_PA for s in p)
    assert all(abs(s.temperature_degc - 23.456) <= T_TOL_DEGC for s in t)
    gaps = {b.t_ns - a.t_ns for a, b in itertools.pairwise(p)}
    assert gaps == {20_000_000}
    assert rig.emulator.aborted_conversions == 0  # never read a running conversion


def test_sample_time_is_when_the_pressure_conversion_completed() -> None:
    rig = Rig()
    rig.physics(100000.0, 20.0)
    rig.begin()
    start = rig.clock.now_ns()
    first = pressures(rig.run_until(100_000_000))[0]
    # D2 then D1, each waited for its datasheet maximum (9.04 ms at OSR 4096).
    assert first.t_ns == start + 2 * 9_040_000


def test_cold_readings_use_second_order_compensation() -> None:
    rig = Rig()
    rig.physics(70000.0, -25.0)
    rig.begin()
    samples = rig.run_until(200_000_000)
    assert all(abs(s.pressure_pa - 70000.0) <= P_TOL_PA for s in pressures(samples))
    assert all(abs(s.temperature_degc + 25.0) <= T_TOL_DEGC for s in temperatures(samples))


def test_fast_low_osr_settings_and_sparse_temperature() -> None:
    rig = Rig(pressure_oversampling=1024, temperature_oversampling=256, odr_hz=200,
              temperature_every=4)
    rig.physics(101325.0, 30.0)
    rig.begin()
    samples = rig.run_until(500_000_000)
    p, t = pressures(samples), temperatures(samples)
    assert {b.t_ns - a.t_ns for a, b in itertools.pairwise(p)} == {5_000_000}
    assert len(t) == pytest.approx(len(p) / 4, abs=1)
    assert all(abs(s.pressure_pa - 101325.0) <= P_TOL_PA for s in p)


def test_pressure_change_is_followed() -> None:
    rig = Rig()
    rig.physics(100000.0, 20.0)
    rig.begin()
    rig.run_until(100_000_000)
    rig.physics(99000.0, 20.0)
    later = pressures(rig.run_until(200_000_000))
    assert abs(later[-1].pressure_pa - 99000.0) <= P_TOL_PA


def test_early_polls_do_nothing() -> None:
    """Polling more often than asked must not read a conversion early."""
    rig = Rig()
    rig.physics(100000.0, 20.0)
    rig.begin()
    samples: list[Sample] = []
    for t in range(0, 200_000_000, 700_000):
        rig.clock.sleep_until(t)
        rig.dither()  # the chip's own noise: a constant D1 word is a hung converter
        samples += rig.driver.poll(rig.clock.now_ns()).samples
    assert rig.emulator.aborted_conversions == 0
    assert len(pressures(samples)) >= 9 and all(s.valid for s in samples)


def test_late_polls_slide_samples_but_never_read_early() -> None:
    """A busy host polls up to 3 ms late (seeded): samples stay correct and never closer
    together than 1/odr_hz."""
    rng = random.Random(5611)
    rig = Rig()
    rig.physics(100500.0, 21.0)
    rig.begin()
    samples: list[Sample] = []
    while rig.next_ns <= 1_000_000_000:
        rig.clock.sleep_until(rig.next_ns + rng.randrange(0, 3_000_000))
        rig.dither()
        result = rig.driver.poll(rig.clock.now_ns())
        samples += result.samples
        rig.next_ns = result.next_poll_ns
    p = pressures(samples)
    assert rig.emulator.aborted_conversions == 0
    assert all(s.valid and abs(s.pressure_pa - 100500.0) <= P_TOL_PA for s in p)
    assert min(b.t_ns - a.t_ns for a, b in itertools.pairwise(p)) >= 20_000_000
    assert len(p) >= 40


def test_probe_identity_names_the_crc() -> None:
    rig = Rig()
    identity = rig.driver.probe()
    stored = rig.emulator.factory_prom[7] & 0xF
    assert identity.identity == f"PROM CRC4=0x{stored:X}"
    assert (identity.driver, identity.bus, identity.address) == ("ms5611", "i2c-test", 0x77)


def test_absent_chip_is_device_not_found() -> None:
    rig = Rig()
    rig.emulator.absent = True
    with pytest.raises(DeviceNotFoundError) as info:
        rig.driver.probe()
    text = str(info.value)
    for part in ("i2c-test", "0x77", "MS5611 PROM with valid CRC4", "NACK"):
        assert part in text


def test_all_ones_prom_hints_at_wiring_and_address() -> None:
    rig = Rig()
    rig.emulator.fill_prom(0xFFFF)
    with pytest.raises(DeviceNotFoundError) as info:
        rig.driver.probe()
    assert info.value.found == "all-0xFFFF PROM"
    assert "0x77 when CSB is low, 0x76 when high" in info.value.hint


def test_all_zero_prom_is_rejected() -> None:
    rig = Rig(BusKind.SPI)
    rig.emulator.fill_prom(0x0000)
    with pytest.raises(DeviceNotFoundError, match="all-0x0000 PROM"):
        rig.driver.probe()


def test_corrupted_prom_reports_both_crcs() -> None:
    rig = Rig()
    rig.emulator.corrupt_prom(2, 9)
    computed = crc4(rig.emulator.factory_prom)
    stored = rig.emulator.factory_prom[7] & 0xF
    assert computed != stored
    with pytest.raises(DeviceNotFoundError) as info:
        rig.driver.probe()
    assert info.value.found == f"CRC4 0x{computed:X} but stored 0x{stored:X}"
    assert "0x77" in str(info.value)


def test_bus_error_mid_conversion_then_recover() -> None:
    rig = Rig()
    rig.physics(98000.0, 18.0)
    rig.begin()
    rig.run_until(50_000_000)
    assert rig.emulator.converting  # the failing transfer is the ADC read that ends it
    rig.bus.fail_transfers({1})
    with pytest.raises(BusError):
        rig.run_until(100_000_000)
    rig.next_ns = rig.driver.recover(rig.clock.now_ns())
    assert rig.driver.health.reconfigurations == 1
    samples = rig.run_until(rig.clock.now_ns() + 200_000_000)
    assert len(pressures(samples)) >= 9
    assert all(s.valid for s in samples)
    assert all(abs(s.pressure_pa - 98000.0) <= P_TOL_PA for s in pressures(samples))


@pytest.mark.parametrize(
    ("reset_at_ns", "running"),
    [(45_000_000, Measurement.D2), (55_000_000, Measurement.D1)],
    ids=["during-temperature", "during-pressure"],
)
def test_silent_reset_gives_one_stale_slot_then_recovers(
    reset_at_ns: int, running: Measurement
) -> None:
    rig = Rig()
    rig.physics(98000.0, 18.0)
    rig.begin()
    rig.run_until(reset_at_ns)
    assert rig.emulator.running is running
    rig.emulator.silent_reset()
    samples = rig.run_until(300_000_000)
    stale = [s for s in samples if s.flags & SampleFlag.STALE]
    assert len(pressures(stale)) == 1
    after = pressures(samples)[-5:]
    assert all(s.valid and abs(s.pressure_pa - 98000.0) <= P_TOL_PA for s in after)


def test_out_of_datasheet_range_values_are_flagged() -> None:
    rig = Rig()
    rig.physics(125000.0, 25.0)  # P above 1200 mbar, TEMP fine
    rig.begin()
    samples = rig.run_until(100_000_000)
    assert all(s.flags == SampleFlag.OUT_OF_RANGE for s in pressures(samples))
    assert all(s.valid for s in temperatures(samples))
    rig.physics(100000.0, 90.0)  # TEMP above 85 degC taints the compensated pressure too
    samples = rig.run_until(200_000_000)[-4:]
    assert all(s.flags & SampleFlag.OUT_OF_RANGE for s in samples)


def test_settings_reject_an_unknown_osr_listing_the_allowed_ones() -> None:
    with pytest.raises(ValidationError) as info:
        MS5611Settings(pressure_oversampling=8192)
    for allowed in ("256", "512", "1024", "2048", "4096"):
        assert allowed in str(info.value)


def test_settings_reject_a_rate_the_conversions_cannot_reach() -> None:
    # 4096/4096: 9.04 + 9.04 ms per slot -> at most 55.31 Hz.
    with pytest.raises(ValidationError, match=r"maximum is 55\.31 Hz"):
        MS5611Settings(odr_hz=60)
    assert MS5611Settings(odr_hz=55).odr_hz == 55


def test_settings_are_physical_and_closed() -> None:
    with pytest.raises(ValidationError):
        MS5611Settings(osr_code=4)
    with pytest.raises(ValidationError):
        MS5611Settings(temperature_every=0)


def test_plugin_registers_driver_and_emulator() -> None:
    registry = load_registry()
    assert registry.drivers.get("ms5611") is MS5611Driver
    assert registry.emulators.get("ms5611") is MS5611Emulator


def test_a_poll_that_runs_late_waits_for_the_conversion_from_when_it_really_started() -> None:
    """Other devices' transfers can delay a poll past the time the pipeline hands the
    driver: the conversion then starts later than ``now_ns`` says, and the ADC read must
    still come after it has finished (a read during a conversion returns 0 and aborts it)."""
    rng = random.Random(5611)
    rig = Rig()
    rig.physics(100500.0, 21.0)
    rig.begin()
    samples: list[Sample] = []
    while rig.next_ns <= 500_000_000:
        # the bus was busy for up to 2 ms (more than the 0.8 ms between the typical and
        # the maximum conversion time)
        rig.clock.sleep_until(rig.next_ns + rng.randrange(0, 2_000_000))
        rig.dither()
        result = rig.driver.poll(rig.next_ns)           # told the nominal time
        samples += result.samples
        rig.next_ns = max(result.next_poll_ns, rig.clock.now_ns())
    assert rig.emulator.aborted_conversions == 0
    assert len(pressures(samples)) > 20 and all(s.valid for s in samples)


def test_the_slot_that_ends_a_frozen_run_is_frozen_too() -> None:
    """Issue 9 item 3 (frozen data): the converter hangs, then recovers between a cycle's
    temperature conversion and its pressure conversion. That pressure word is new, but the
    temperature word is the hung converter's (15 degC against a true 25 degC), and D2 words
    cannot show it (temperature noise is under a count): the slot is FROZEN, and the next
    cycle converts a new temperature."""
    rig = Rig()
    rig.physics(95000.0, 15.0)
    rig.begin()
    assert all(s.valid for s in rig.run_until(200_000_000))
    rig.emulator.frozen = True
    frozen = rig.run_until(500_000_000)
    assert pressures(frozen)[-1].flags & SampleFlag.FROZEN
    # step one poll at a time until the temperature conversion of a cycle is running
    for _ in range(1000):
        rig.run_until(rig.next_ns)
        if rig.emulator.running is Measurement.D2:
            break
    else:
        pytest.fail("no temperature conversion started")
    rig.emulator.frozen = False
    rig.physics(96000.0, 25.0)
    rig.dither = lambda: None  # type: ignore[assignment]  # exact values from here
    after = rig.run_until(rig.clock.now_ns() + 200_000_000)
    assert pressures(after)[0].flags & SampleFlag.FROZEN
    assert temperatures(after)[0].flags & SampleFlag.FROZEN
    valid = [s for s in after if s.valid]
    assert valid and all(abs(s.temperature_degc - 25.0) <= T_TOL_DEGC
                         for s in temperatures(valid))


def _fail_next_transfer_of(rig: Rig, in_state: Measurement | None) -> None:
    """Step polls until the next poll's transfer is an ADC read (``in_state``: the running
    conversion) or a convert command (None: no conversion running), then fail it."""
    for _ in range(1000):
        rig.run_until(rig.next_ns)
        running = rig.emulator.running
        if in_state is None and running is None and rig.clock.now_ns() > 100_000_000:
            rig.clock.sleep_until(rig.next_ns)
            if rig.emulator.running is None:
                break
        if in_state is not None and running is in_state:
            break
    rig.bus.fail_transfers({1})
    rig.clock.sleep_until(rig.next_ns)
    with pytest.raises(BusError):
        rig.driver.poll(rig.clock.now_ns())


@pytest.mark.parametrize("running", [Measurement.D2, Measurement.D1],
                         ids=["temperature", "pressure"])
def test_a_failed_adc_read_is_retried_without_a_reset_and_keeps_the_sample(
        running: Measurement) -> None:
    """Issue 9 (proportionate recovery): a glitch on the ADC read costs no reset, no PROM
    reload and no sample; the next slots are all valid."""
    rig = Rig()
    rig.physics(98000.0, 18.0)
    rig.begin()
    _fail_next_transfer_of(rig, running)
    resets = rig.emulator.resets
    next_ns = rig.driver.resume(rig.clock.now_ns())
    assert next_ns is not None
    rig.next_ns = next_ns
    samples = rig.run_until(rig.clock.now_ns() + 200_000_000)
    assert rig.emulator.resets == resets
    assert rig.emulator.aborted_conversions == 0
    assert len(pressures(samples)) >= 10
    assert all(s.valid and abs(s.pressure_pa - 98000.0) <= P_TOL_PA
               for s in pressures(samples))


def test_a_failed_convert_command_waits_out_a_conversion_it_may_have_started() -> None:
    """A convert command that failed may still have reached the chip; converting again at
    once would overlap it and give a wrong result. resume() waits the conversion's maximum
    time, then the cycle goes on without a reset."""
    rig = Rig()
    rig.physics(98000.0, 18.0)
    rig.begin()
    _fail_next_transfer_of(rig, None)
    now = rig.clock.now_ns()
    next_ns = rig.driver.resume(now)
    assert next_ns is not None and next_ns - now >= 9_000_000  # OSR 4096 maximum time
    rig.next_ns = next_ns
    samples = rig.run_until(now + 200_000_000)
    assert rig.emulator.aborted_conversions == 0
    assert pressures(samples) and all(s.valid for s in samples)


def test_resume_declines_when_the_failed_transfer_is_not_a_poll_transfer() -> None:
    """Before probing (no PROM) or after a failure outside a conversion's transfers, only
    the full recovery will do."""
    rig = Rig()
    assert rig.driver.resume(0) is None
    rig.physics(98000.0, 18.0)
    rig.begin()
    rig.run_until(100_000_000)
    assert rig.driver.resume(rig.clock.now_ns()) is None
