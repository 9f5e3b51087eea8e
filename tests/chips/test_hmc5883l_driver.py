"""HMC5883L driver against its emulator: directly on I2C and, unchanged, behind the
MAX21100's aux I2C master over SPI (the seed board). Tolerance: one LSB of the gain."""

from __future__ import annotations

import itertools
import random
from dataclasses import dataclass

import pytest
from tests.support.dither import Dither
from tests.support.driving import poll_until

from imuhal.bus.base import BusKind, Link
from imuhal.core.clock import SimulatedClock
from imuhal.core.errors import BusError, DeviceNotFoundError
from imuhal.core.samples import MagSample, Quantity, Sample, SampleFlag
from imuhal.emulation import EmulatedBus, PhysicalInputs
from imuhal_chips.hmc5883l.driver import Hmc5883lDriver
from imuhal_chips.hmc5883l.emulator import Hmc5883lEmulator
from imuhal_chips.hmc5883l.registers import AVERAGING, ODR_HZ, RANGE_GAUSS
from imuhal_chips.max2110x.driver import Max21100Driver
from imuhal_chips.max2110x.emulator import Max21100Emulator

PATHS = ["i2c", "max21100-aux"]
EARTH_UT = (20.0, -3.0, 43.0)


@dataclass
class Rig:
    clock: SimulatedClock
    bus: EmulatedBus
    emu: Hmc5883lEmulator
    driver: Hmc5883lDriver
    next_ns: int = 0
    dither: Dither | None = None

    def run(self, seconds: float) -> list[Sample]:
        """Poll for ``seconds``, the field dithered by half an LSB as a real chip's noise
        would (tests/support/dither.py)."""
        end = self.clock.now_ns() + round(seconds * 1e9)
        out, self.next_ns = poll_until(self.driver, self.clock, self.next_ns, end,
                                       self.dither)
        return out


def make_rig(path: str = "i2c", *, start: bool = True, **settings: object) -> Rig:
    clock = SimulatedClock()
    emu = Hmc5883lEmulator(clock)
    if path == "i2c":
        bus = EmulatedBus("i2c1", BusKind.I2C)
        bus.attach(0x1E, emu)
        link: Link = bus.link(0x1E)
    else:  # the seed board: everything over SPI, the HMC5883L behind the MAX21100
        bus = EmulatedBus("spi0", BusKind.SPI)
        imu_emu = bus.attach(0, Max21100Emulator(clock))
        imu_emu.child_buses()["aux"].attach(0x1E, emu)
        imu = Max21100Driver(bus.link(0), {}, device="imu", clock=clock)
        imu.probe()
        imu.configure()
        link = imu.child_buses()["aux"].link(0x1E)
    # An Earth-like field: an all-zero data frame is what an undriven bus reads (BLANK).
    emu.set_physics(PhysicalInputs(magnetic_field_ut=EARTH_UT))
    driver = Hmc5883lDriver(link, settings, device="mag", clock=clock)
    rig = Rig(clock, bus, emu, driver, dither=Dither(emu, seed=5883))
    if start:
        driver.probe()
        driver.configure()
        rig.next_ns = driver.start(clock.now_ns())
    return rig


def mags(samples: list[Sample]) -> list[MagSample]:
    return [s for s in samples if isinstance(s, MagSample)]


@pytest.mark.parametrize("path", PATHS)
def test_probe_finds_h43(path: str) -> None:
    rig = make_rig(path, start=False)
    assert rig.driver.probe().identity == "ID=H43"


def test_absent_chip_on_i2c_is_device_not_found_naming_bus_and_address() -> None:
    rig = make_rig(start=False)
    rig.emu.absent = True
    with pytest.raises(DeviceNotFoundError, match=r"i2c1 at address/cs 0x1E.*NACK"):
        rig.driver.probe()


def test_absent_chip_behind_the_master_reads_ff_and_hints_at_wiring() -> None:
    rig = make_rig("max21100-aux", start=False)
    rig.emu.absent = True
    with pytest.raises(DeviceNotFoundError, match=r"found ID bytes ff ff ff.*pull-ups"):
        rig.driver.probe()


def test_clone_with_other_identity_is_rejected_with_the_bytes_found() -> None:
    rig = make_rig(start=False)
    rig.emu.identity = b"\x00\x00\x00"
    with pytest.raises(DeviceNotFoundError, match=r"expected .*'H43'.*found ID bytes 00 00 00"):
        rig.driver.probe()


@pytest.mark.parametrize("path", PATHS)
def test_configure_writes_the_seed_settings(path: str) -> None:
    rig = make_rig(path)
    assert (rig.emu.regs[0], rig.emu.regs[1], rig.emu.regs[2]) == (0x78, 0x20, 0x00)


@pytest.mark.parametrize("path", PATHS)
def test_field_set_on_the_emulator_reads_back_in_ut_within_one_lsb(path: str) -> None:
    rng = random.Random(5883)
    rig = make_rig(path)
    for _ in range(4):
        field = tuple(rng.uniform(-60.0, 60.0) for _ in range(3))
        rig.emu.set_physics(PhysicalInputs(magnetic_field_ut=field))
        rig.run(0.03)
        got = mags(rig.run(0.05))
        assert got and all(s.valid for s in got)
        assert got[-1].mag_ut == pytest.approx(field, abs=rig.emu.resolution(Quantity.MAG))


@pytest.mark.parametrize("range_gauss", sorted(RANGE_GAUSS))
def test_every_range_reads_a_field_near_its_limit_within_one_lsb(range_gauss: float) -> None:
    rig = make_rig(range_gauss=range_gauss)
    field = (0.9 * range_gauss * 100, -0.5 * range_gauss * 100, 0.2 * range_gauss * 100)
    rig.emu.set_physics(PhysicalInputs(magnetic_field_ut=field))
    got = mags(rig.run(0.05))
    assert got and all(s.valid for s in got)
    assert got[-1].mag_ut == pytest.approx(field, abs=rig.emu.resolution(Quantity.MAG))


@pytest.mark.parametrize("odr_hz", sorted(ODR_HZ))
def test_every_output_rate_gives_that_many_samples_per_second(odr_hz: float) -> None:
    rig = make_rig(odr_hz=odr_hz, averaging=1)
    rig.emu.set_physics(PhysicalInputs(magnetic_field_ut=(20.3, -1.7, 40.6)))
    seconds = max(1.0, 4 / odr_hz)
    got = mags(rig.run(seconds))
    # one sample per output period; the first period's sample is dropped (old gain)
    assert len(got) >= odr_hz * seconds - 2
    gaps = {b.t_ns - a.t_ns for a, b in itertools.pairwise(got)}
    assert gaps and all(abs(g - 1e9 / odr_hz) <= 1 for g in gaps)
    assert all(s.valid for s in got)
    assert got[-1].mag_ut == pytest.approx((20.3, -1.7, 40.6), abs=0.1)


@pytest.mark.parametrize("averaging", sorted(AVERAGING))
def test_averaging_is_written_to_config_a(averaging: int) -> None:
    rig = make_rig(averaging=averaging)
    assert rig.emu.regs[0] >> 5 == AVERAGING[averaging]


def test_first_sample_after_configure_is_dropped_because_it_uses_the_old_gain() -> None:
    rig = make_rig(range_gauss=4.0)  # gain 440; the power-on gain is 1090
    rig.emu.set_physics(PhysicalInputs(magnetic_field_ut=(100.0, 0.0, 0.0)))
    got = mags(rig.run(0.1))
    assert rig.emu.measurements >= len(got) + 1
    assert all(s.mag_ut[0] == pytest.approx(100.0, abs=0.23) for s in got)


@pytest.mark.parametrize("path", PATHS)
def test_field_beyond_range_is_flagged_overflow_and_never_valid(path: str) -> None:
    rig = make_rig(path)
    rig.emu.set_physics(PhysicalInputs(magnetic_field_ut=(30.0, 190.0, 10.0)))
    got = mags(rig.run(0.05))
    assert got and all(s.flags & SampleFlag.OVERFLOW and not s.valid for s in got)
    rig.emu.set_physics(PhysicalInputs(magnetic_field_ut=(30.0, 90.0, 10.0)))
    # the 8-sample average may still hold overflowed measurements for 7 outputs (93 ms)
    settling = mags(rig.run(0.03))
    assert settling and all(s.flags == SampleFlag.FILTER_SETTLING for s in settling)
    rig.run(0.08)
    assert all(s.valid for s in mags(rig.run(0.05)))


@pytest.mark.parametrize("path", PATHS)
def test_silent_reset_is_detected_counted_and_reconfigured(path: str) -> None:
    rig = make_rig(path, reset_check_s=0.2)
    rig.emu.set_physics(PhysicalInputs(magnetic_field_ut=(25.0, -5.0, 40.0)))
    rig.run(0.1)
    rig.emu.silent_reset()
    rig.run(0.3)
    assert rig.driver.health.resets_detected == 1
    assert rig.emu.regs[2] == 0x00
    rig.emu.set_physics(PhysicalInputs(magnetic_field_ut=(-25.0, 5.0, 10.0)))
    rig.run(0.03)
    got = mags(rig.run(0.05))
    assert got and all(s.valid for s in got)
    assert got[-1].mag_ut == pytest.approx((-25.0, 5.0, 10.0), abs=0.1)


def test_stuck_data_ready_flags_stale_then_the_driver_restarts_the_chip() -> None:
    rig = make_rig()
    rig.run(0.05)
    rig.emu.stuck_data_ready = True
    got = mags(rig.run(0.15))
    assert any(s.flags & SampleFlag.STALE for s in got)
    assert rig.driver.health.reconfigurations == 1
    after = mags(rig.run(0.1))
    assert len(after) >= 6 and all(s.valid for s in after)


def test_recover_after_a_bus_error_resumes_sampling() -> None:
    rig = make_rig()
    rig.run(0.05)
    rig.bus.fail_transfers({1})
    rig.clock.sleep_until(rig.next_ns)
    with pytest.raises(BusError):
        rig.driver.poll(rig.clock.now_ns())
    rig.next_ns = rig.driver.recover(rig.clock.now_ns())
    assert rig.driver.health.reconfigurations == 1
    got = mags(rig.run(0.2))
    assert len(got) >= 13 and all(s.valid for s in got)


def test_driver_registered_through_the_plugin_hooks() -> None:
    from imuhal.plugins.manager import load_registry
    from imuhal_chips.hmc5883l import plugin

    registry = load_registry(entry_point_plugins=False, extra=[("hmc5883l", plugin)])
    assert registry.drivers.get("hmc5883l") is Hmc5883lDriver
    assert registry.emulators.get("hmc5883l") is Hmc5883lEmulator
    assert Hmc5883lDriver.bus_kinds == {BusKind.I2C}


@pytest.mark.parametrize("found", [b"H\xff3", b"\xff43", b"H4\xff"])
def test_an_identity_read_partly_unanswered_is_a_bus_error_not_another_chip(
        found: bytes) -> None:
    """Issue 26 item 8: behind the MAX21100's master, a byte the slave does not answer on a
    noisy bus (10 % errors) reads 0xFF; "48 ff 33" was reported as another chip or a clone
    (and two such reads in a row stopped the board)."""
    rig = make_rig("spi", start=False)
    rig.emu.identity = found
    with pytest.raises(BusError, match="unanswered"):
        rig.driver.probe()


def test_an_identity_of_another_chip_is_still_a_wrong_chip() -> None:
    rig = make_rig("spi", start=False)
    rig.emu.identity = b"H\xff5"
    with pytest.raises(DeviceNotFoundError):
        rig.driver.probe()
