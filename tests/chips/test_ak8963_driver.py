"""AK8963 driver against its register-level emulator on an I2C bus, one simulated clock."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import pytest
from tests.support.driving import poll_count

from imuhal.bus.base import BusKind
from imuhal.core.clock import SimulatedClock
from imuhal.core.errors import BusError, DeviceNotFoundError
from imuhal.core.samples import Quantity, SampleFlag
from imuhal.emulation import EmulatedBus, PhysicalInputs
from imuhal_chips.ak8963 import registers as r
from imuhal_chips.ak8963.driver import AK8963Driver, AK8963Settings
from imuhal_chips.ak8963.emulator import AK8963Emulator


@dataclass
class Rig:
    clock: SimulatedClock
    bus: EmulatedBus
    emu: AK8963Emulator
    driver: AK8963Driver

    def ready(self) -> Rig:
        self.driver.probe()
        self.driver.configure()
        return self

    def run(self, n: int, start: int | None = None) -> list[Any]:
        return poll_count(self.driver, self.clock, n, start=start, max_polls=20 * n + 20)



def rig(**settings: Any) -> Rig:
    clock = SimulatedClock()
    bus = EmulatedBus("i2c1", BusKind.I2C)
    emu = bus.attach(r.I2C_ADDRESS, AK8963Emulator(clock))
    return Rig(clock, bus, emu,
               AK8963Driver(bus.link(r.I2C_ADDRESS), settings, device="mag", clock=clock))


def test_configure_reads_asa_in_fuse_rom_mode_and_never_skips_power_down() -> None:
    k = rig().ready()
    assert k.driver.asa == k.emu.asa
    assert k.emu.mode_violations == 0
    assert k.emu._read(r.REG_ASAX) == 0  # outside fuse-ROM mode ASA is not readable


@pytest.mark.parametrize("odr_hz", [8, 100])
@pytest.mark.parametrize("bits", [14, 16])
def test_every_setting_reads_the_true_field_within_one_lsb(odr_hz: int, bits: int) -> None:
    k = rig(odr_hz=odr_hz, resolution_bits=bits).ready()
    fs = k.emu.full_scale(Quantity.MAG)
    truth = (0.31 * fs, -0.27 * fs, 0.19 * fs)
    k.emu.set_physics(PhysicalInputs(magnetic_field_ut=truth))
    samples = k.run(3)
    assert len(samples) == 3 and all(s.valid for s in samples)
    lsb = k.emu.resolution(Quantity.MAG)
    for got, want in zip(samples[-1].mag_ut, truth, strict=True):
        assert abs(got - want) <= lsb
    # consecutive samples one ODR period apart (within one retry step of 10 %)
    dt = (samples[-1].t_ns - samples[-2].t_ns) / 1e9
    assert dt == pytest.approx(1 / odr_hz, rel=0.15)


def test_settings_list_allowed_values() -> None:
    with pytest.raises(ValueError, match="8 or 100"):
        AK8963Settings(odr_hz=50)
    with pytest.raises(ValueError, match="14 or 16"):
        AK8963Settings(resolution_bits=12)


def test_field_beyond_range_is_overflow_and_saturated() -> None:
    k = rig().ready()
    k.emu.set_physics(PhysicalInputs(magnetic_field_ut=(6000.0, 10.0, 10.0)))
    sample = k.run(1)[0]
    assert SampleFlag.OVERFLOW in sample.flags and SampleFlag.SATURATED in sample.flags
    assert not sample.valid


def test_hofl_alone_makes_the_sample_invalid() -> None:
    k = rig().ready()
    k.emu.set_physics(PhysicalInputs(magnetic_field_ut=(2000.0, 2000.0, 1000.0)))  # sum 5000
    sample = k.run(1)[0]
    assert sample.flags == SampleFlag.OVERFLOW


def test_unread_measurement_overwritten_sets_dor() -> None:
    k = rig(odr_hz=100).ready()
    k.clock.sleep(0.035)  # three measurements, none read
    st1 = k.bus.transfer(r.I2C_ADDRESS, bytes([r.REG_ST1]), 1)[0]
    assert st1 == r.ST1_DRDY | r.ST1_DOR


def test_data_stay_protected_until_st2_is_read() -> None:
    k = rig(odr_hz=100).ready()
    k.emu.set_physics(PhysicalInputs(magnetic_field_ut=(10.0, 0.0, 0.0)))
    k.clock.sleep(0.0075)
    first = k.bus.transfer(r.I2C_ADDRESS, bytes([r.REG_HXL]), 2)  # starts the data read
    k.emu.set_physics(PhysicalInputs(magnetic_field_ut=(20.0, 0.0, 0.0)))
    k.clock.sleep(0.010)  # next measurement completes during the read
    again = k.bus.transfer(r.I2C_ADDRESS, bytes([r.REG_HXL]), 2)
    assert again == first
    k.bus.transfer(r.I2C_ADDRESS, bytes([r.REG_ST2]), 1)  # ends the read
    st1, xl, xh = k.bus.transfer(r.I2C_ADDRESS, bytes([r.REG_ST1]), 3)
    assert st1 & r.ST1_DRDY and int.from_bytes(bytes([xl, xh]), "little") > \
        int.from_bytes(first, "little")


def test_wrong_identity_names_expected_and_found() -> None:
    k = rig()
    k.emu.wia = 0x49
    with pytest.raises(DeviceNotFoundError) as err:
        k.driver.probe()
    assert err.value.found == "0x49" and "0x48" in err.value.expected
    assert err.value.address == 0x0C and err.value.bus == "i2c1"


def test_absent_chip_hints_at_the_mpu9250_aux_bus() -> None:
    k = rig()
    k.emu.absent = True
    with pytest.raises(DeviceNotFoundError) as err:
        k.driver.probe()
    assert "aux" in err.value.hint and "NACK" in err.value.found


def test_stuck_data_ready_gives_stale_samples_and_recover_works() -> None:
    k = rig(odr_hz=100).ready()
    k.emu.stuck_data_ready = True
    samples = k.run(2)
    assert len(samples) == 2 and all(s.flags & SampleFlag.STALE for s in samples)
    assert all(math.isnan(v) for v in samples[0].mag_ut)
    k.emu.stuck_data_ready = False
    start = k.driver.recover(k.clock.now_ns())
    assert all(s.valid for s in k.run(2, start))


def test_silent_reset_is_detected_counted_and_repaired() -> None:
    k = rig(odr_hz=100).ready()
    k.run(2)
    k.emu.silent_reset()
    samples = k.run(3)
    assert k.driver.health.resets_detected == 1
    assert k.driver.health.reconfigurations == 1
    assert samples[-1].valid


def test_bus_error_raises_and_recover_restores() -> None:
    k = rig().ready()
    k.run(1)
    k.bus.fail_transfers({1})
    with pytest.raises(BusError):
        k.driver.poll(k.clock.now_ns())
    start = k.driver.recover(k.clock.now_ns())
    assert all(s.valid for s in k.run(2, start))
