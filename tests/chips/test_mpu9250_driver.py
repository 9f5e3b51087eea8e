"""MPU-9250 driver against its register-level emulator (I2C and SPI), one simulated clock,
including the AK8963 reached through bypass (MPU on I2C) and the I2C master (MPU on SPI)."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import pytest

from imuhal.bus.base import BusKind
from imuhal.core.clock import SimulatedClock
from imuhal.core.errors import BusError, ConfigurationError, DeviceNotFoundError, NackError
from imuhal.core.samples import AccelSample, GyroSample, MagSample, Quantity, SampleFlag
from imuhal.drivers.base import Driver
from imuhal.emulation import EmulatedBus, PhysicalInputs
from imuhal_chips.ak8963.driver import AK8963Driver
from imuhal_chips.ak8963.emulator import AK8963Emulator
from imuhal_chips.mpu9250 import registers as r
from imuhal_chips.mpu9250.driver import MPU9250Driver, MPU9250Settings
from imuhal_chips.mpu9250.emulator import MPU9250Emulator

G = r.STANDARD_GRAVITY_M_S2


@dataclass
class Rig:
    clock: SimulatedClock
    bus: EmulatedBus
    emu: MPU9250Emulator
    ak: AK8963Emulator
    driver: MPU9250Driver
    target: int
    extra: list[Driver] = field(default_factory=list)

    def ready(self) -> Rig:
        self.driver.probe()
        self.driver.configure()
        return self

    def run(self, n: int, *, drivers: list[Driver] | None = None,
            starts: list[int] | None = None) -> list[Any]:
        """Poll all drivers on the shared clock until ``n`` samples came out."""
        drivers = drivers or [self.driver]
        due = starts or [d.start(self.clock.now_ns()) for d in drivers]
        out: list[Any] = []
        for _ in range(40 * n + 40):
            i = min(range(len(drivers)), key=lambda k: due[k])
            self.clock.sleep_until(due[i])
            result = drivers[i].poll(self.clock.now_ns())
            out.extend(result.samples)
            due[i] = result.next_poll_ns
            if len(out) >= n:
                break
        return out


def rig(kind: BusKind = BusKind.I2C, **settings: Any) -> Rig:
    clock = SimulatedClock()
    bus = EmulatedBus("host", kind)
    target = 0x68 if kind is BusKind.I2C else 0
    emu = bus.attach(target, MPU9250Emulator(clock))
    ak = emu.aux_bus.attach(0x0C, AK8963Emulator(clock))
    if kind is BusKind.I2C:
        emu.connect_bypass(bus)
    driver = MPU9250Driver(bus.link(target), settings, device="imu", clock=clock)
    return Rig(clock, bus, emu, ak, driver, target)


def of(samples: list[Any], cls: type) -> list[Any]:
    return [s for s in samples if isinstance(s, cls)]


@pytest.mark.parametrize("kind", [BusKind.I2C, BusKind.SPI])
def test_level_chip_reads_plus_one_g_on_z(kind: BusKind) -> None:
    k = rig(kind).ready()
    accel = of(k.run(6), AccelSample)[-1]
    assert accel.valid
    assert accel.accel_m_s2 == pytest.approx((0.0, 0.0, G), abs=k.emu.resolution(Quantity.ACCEL))


SWEEP = (
    [{"gyro_range_dps": v} for v in (250, 500, 1000, 2000)]
    + [{"accel_range_g": v} for v in (2, 4, 8, 16)]
    + [{"gyro_lpf_hz": v} for v in (184, 92, 41, 20, 10, 5)]
    + [{"gyro_lpf_hz": v, "odr_hz": 8000} for v in (250, 3600)]
    + [{"accel_lpf_hz": v} for v in (460, 184, 92, 41, 20, 10, 5, 1130)]
    + [{"odr_hz": v} for v in (1000, 500, 250, 100, 50, 1000 / 256)]
)


@pytest.mark.parametrize("setting", SWEEP, ids=lambda s: "-".join(f"{k}={v:g}" for k, v in
                                                                  s.items()))
def test_every_setting_reads_physics_within_one_lsb(setting: dict[str, Any]) -> None:
    k = rig(**setting).ready()
    fa, fg = k.emu.full_scale(Quantity.ACCEL), k.emu.full_scale(Quantity.GYRO)
    force, rate = (0.71 * fa, -0.33 * fa, 0.05 * fa), (-0.62 * fg, 0.27 * fg, 0.91 * fg)
    k.emu.set_physics(PhysicalInputs(specific_force_m_s2=force, angular_rate_rad_s=rate,
                                     temperature_degc=36.6))
    samples = k.run(9)
    accel, gyro = of(samples, AccelSample)[-1], of(samples, GyroSample)[-1]
    assert accel.valid and gyro.valid
    assert accel.accel_m_s2 == pytest.approx(force, abs=k.emu.resolution(Quantity.ACCEL))
    assert gyro.gyro_rad_s == pytest.approx(rate, abs=k.emu.resolution(Quantity.GYRO))
    temp = samples[-1] if samples[-1].channel is Quantity.TEMPERATURE else None
    assert temp is not None
    assert abs(temp.temperature_degc - 36.6) <= k.emu.resolution(Quantity.TEMPERATURE)
    # samples are one output period apart, each within a poll guard after its measurement
    ts = [s.t_ns for s in of(samples, AccelSample)]
    assert abs(ts[-1] - ts[-2] - k.emu.period_ns()) <= k.emu.period_ns() // 8
    measured = k.emu.measured_ns
    assert 0 <= ts[-1] - measured[measured.count_until(ts[-1]) - 1] <= k.emu.period_ns() // 8


def test_settings_errors_list_the_allowed_values() -> None:
    with pytest.raises(ValueError, match="250, 500, 1000 or 2000"):
        MPU9250Settings(gyro_range_dps=300)
    with pytest.raises(ValueError, match="nearest allowed"):
        MPU9250Settings(odr_hz=300)
    with pytest.raises(ValueError, match="fixed at 8000"):
        MPU9250Settings(gyro_lpf_hz=250, odr_hz=1000)


def test_bypass_on_spi_is_refused_with_the_alternative() -> None:
    clock = SimulatedClock()
    bus = EmulatedBus("spi0", BusKind.SPI)
    with pytest.raises(ConfigurationError, match="aux: master"):
        MPU9250Driver(bus.link(0), {"aux": "bypass"}, device="imu", clock=clock)


def test_full_scale_input_is_saturated() -> None:
    k = rig(accel_range_g=2, gyro_range_dps=250).ready()
    k.emu.set_physics(PhysicalInputs(specific_force_m_s2=(3 * G, 0.0, 0.0),
                                     angular_rate_rad_s=(0.0, 0.0, -10.0)))
    samples = k.run(3)
    assert of(samples, AccelSample)[-1].flags == SampleFlag.SATURATED
    assert of(samples, GyroSample)[-1].flags == SampleFlag.SATURATED


def test_mpu9255_is_accepted_with_a_note() -> None:
    k = rig()
    k.emu.who_am_i = r.WHO_AM_I_MPU9255
    identity = k.driver.probe()
    assert "MPU-9255" in identity.note and identity.identity == "WHO_AM_I=0x73"


def test_mpu6500_clone_is_rejected_with_a_magnetometer_hint() -> None:
    k = rig()
    k.emu.who_am_i = 0x70
    with pytest.raises(DeviceNotFoundError) as err:
        k.driver.probe()
    e = err.value
    assert (e.bus, e.address, e.found) == ("host", 0x68, "0x70")
    assert "0x71" in e.expected and "no magnetometer" in e.hint


def test_absent_chip_nack_becomes_device_not_found() -> None:
    k = rig()
    k.emu.absent = True
    with pytest.raises(DeviceNotFoundError, match="NACK"):
        k.driver.probe()


def test_stuck_data_ready_gives_stale_and_recover_works() -> None:
    k = rig().ready()
    k.emu.stuck_data_ready = True
    samples = k.run(3)
    assert all(s.flags == SampleFlag.STALE for s in samples)
    assert math.isnan(samples[0].accel_m_s2[0])
    k.emu.stuck_data_ready = False
    start = k.driver.recover(k.clock.now_ns())
    assert all(s.valid for s in k.run(3, starts=[start]))


def test_silent_reset_is_detected_counted_and_repaired() -> None:
    k = rig().ready()
    k.run(3)
    k.emu.silent_reset()
    samples = k.run(3)
    assert k.driver.health.resets_detected == 1
    assert k.driver.health.reconfigurations == 1
    assert all(s.valid for s in samples)
    assert k.emu.bypass_active()  # the aux path came back with the configuration


def test_bus_error_raises_and_recover_restores() -> None:
    k = rig().ready()
    k.run(3)
    k.bus.fail_transfers({1})
    with pytest.raises(BusError):
        k.driver.poll(k.clock.now_ns())
    start = k.driver.recover(k.clock.now_ns())
    assert all(s.valid for s in k.run(3, starts=[start]))


# -- the AK8963 behind the MPU-9250 -----------------------------------------------------------

MAG_TRUTH = (23.4, -5.6, 41.2)


def with_magnetometer(kind: BusKind, aux: str) -> tuple[Rig, AK8963Driver]:
    k = rig(kind, aux=aux).ready()
    k.ak.set_physics(PhysicalInputs(magnetic_field_ut=MAG_TRUTH))
    aux_bus = k.driver.child_buses()["aux"]
    mag = AK8963Driver(aux_bus.link(0x0C), {"odr_hz": 100}, device="mag", clock=k.clock)
    mag.probe()
    mag.configure()
    return k, mag


def test_ak8963_via_bypass_on_the_host_i2c_bus() -> None:
    k, mag = with_magnetometer(BusKind.I2C, "bypass")
    assert k.driver.child_buses()["aux"] is k.bus
    samples = k.run(40, drivers=[k.driver, mag])
    mags = of(samples, MagSample)
    assert mags and all(s.valid for s in mags)
    assert mags[-1].mag_ut == pytest.approx(MAG_TRUTH, abs=k.ak.resolution(Quantity.MAG))
    assert mag.asa == k.ak.asa


def test_ak8963_via_the_i2c_master_with_the_mpu_on_spi() -> None:
    k, mag = with_magnetometer(BusKind.SPI, "master")
    assert not k.emu.bypass_active()
    samples = k.run(40, drivers=[k.driver, mag])
    mags = of(samples, MagSample)
    assert mags and all(s.valid for s in mags)
    assert mags[-1].mag_ut == pytest.approx(MAG_TRUTH, abs=k.ak.resolution(Quantity.MAG))
    assert mag.asa == k.ak.asa and k.ak.mode_violations == 0
    assert all(s.valid for s in of(samples, AccelSample))


def test_ak8963_unreachable_without_bypass() -> None:
    k = rig(BusKind.I2C, aux="off").ready()
    mag = AK8963Driver(k.bus.link(0x0C), {}, device="mag", clock=k.clock)
    with pytest.raises(DeviceNotFoundError, match="aux"):
        mag.probe()


def test_master_transfer_to_an_absent_chip_is_a_nack() -> None:
    k = rig(BusKind.SPI, aux="master").ready()
    aux_bus = k.driver.child_buses()["aux"]
    with pytest.raises(NackError):
        aux_bus.transfer(0x0D, bytes([0x00]), 1)


def test_master_multibyte_read_equals_a_direct_burst() -> None:
    k = rig(BusKind.SPI, aux="master").ready()
    aux_bus = k.driver.child_buses()["aux"]
    via_master = aux_bus.transfer(0x0C, bytes([0x00]), 2)
    direct = k.emu.aux_bus.transfer(0x0C, bytes([0x00]), 2)
    assert via_master == direct == bytes([0x48, 0x9A])


def test_slave0_auto_read_fills_ext_sens_data_big_endian_with_byte_swap() -> None:
    k = rig(BusKind.SPI, aux="master").ready()
    k.ak.set_physics(PhysicalInputs(magnetic_field_ut=MAG_TRUTH))
    aux_bus = k.driver.child_buses()["aux"]
    mag = AK8963Driver(aux_bus.link(0x0C), {}, device="mag", clock=k.clock)
    mag.probe()
    mag.configure()
    link = k.bus.link(0)
    # Linux recipe: SLV0 reads 7 bytes from HXL with BYTE_SW|GRP (big-endian words).
    link.transfer(bytes([r.I2C_SLV0_ADDR, 0x80 | 0x0C, 0x03,
                         r.SLV_EN | r.SLV_BYTE_SW | r.SLV_GRP | 7]))
    k.clock.sleep(0.05)
    k.run(2)
    ext = link.transfer(bytes([0x80 | r.EXT_SENS_DATA_00]), 7)
    hx = int.from_bytes(ext[0:2], "big", signed=True)
    direct = k.ak._data
    assert hx == int.from_bytes(bytes(direct[0:2]), "little", signed=True) != 0
