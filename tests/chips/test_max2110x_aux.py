"""The MAX21100 aux I2C master as a bus, and the seed's paragliding board: MAX21100 on SPI
with the HMC5883L behind its master, both drivers polled on one simulated clock."""

from __future__ import annotations

import math

import pytest
from tests.support.dither import Dither

from imuhal.bus.base import Bus, BusKind
from imuhal.core.clock import SimulatedClock
from imuhal.core.samples import AccelSample, GyroSample, MagSample, Sample
from imuhal.drivers.base import Driver
from imuhal.emulation import ChipEmulator, EmulatedBus, PhysicalInputs
from imuhal_chips.hmc5883l.driver import Hmc5883lDriver
from imuhal_chips.hmc5883l.emulator import Hmc5883lEmulator
from imuhal_chips.max2110x.driver import Max21100Driver
from imuhal_chips.max2110x.emulator import Max21100Emulator


class Recorder(ChipEmulator):
    """An I2C target that records what arrives and answers reads from a 256-byte file."""

    chip = "recorder"

    def __init__(self) -> None:
        super().__init__()
        self.log: list[tuple[bytes, int]] = []
        self.file = bytearray(range(256))

    def bus_transfer(self, kind: BusKind, write: bytes, read_len: int) -> bytes:
        self.log.append((write, read_len))
        if len(write) > 1:
            self.file[write[0]] = write[1]
        return bytes(self.file[write[0] : write[0] + read_len]) if write else b""


def seed_board() -> tuple[SimulatedClock, EmulatedBus, Max21100Emulator, Max21100Driver]:
    clock = SimulatedClock()
    spi = EmulatedBus("spi0", BusKind.SPI)
    imu_emu = spi.attach(0, Max21100Emulator(clock))
    imu = Max21100Driver(spi.link(0), {}, device="imu", clock=clock)
    imu.probe()
    imu.configure()
    return clock, spi, imu_emu, imu


def test_aux_is_an_i2c_bus_and_the_same_object_every_time() -> None:
    _, _, _, imu = seed_board()
    aux = imu.child_buses()["aux"]
    assert isinstance(aux, Bus) and aux.kind is BusKind.I2C
    assert imu.child_buses()["aux"] is aux
    assert aux.lock is imu.link.bus.lock  # one-shot sequences never interleave


def test_multi_byte_write_becomes_one_shot_byte_writes_to_consecutive_registers() -> None:
    _, _, imu_emu, imu = seed_board()
    target = imu_emu.child_buses()["aux"].attach(0x30, Recorder())
    imu.child_buses()["aux"].transfer(0x30, bytes([0x10, 0xA1, 0xA2, 0xA3]), 0)
    assert target.log == [(bytes([0x10, 0xA1]), 0), (bytes([0x11, 0xA2]), 0),
                          (bytes([0x12, 0xA3]), 0)]


def test_multi_byte_read_becomes_one_shot_byte_reads_and_a_bare_read_continues() -> None:
    _, _, imu_emu, imu = seed_board()
    target = imu_emu.child_buses()["aux"].attach(0x30, Recorder())
    aux = imu.child_buses()["aux"]
    assert aux.transfer(0x30, b"\x40", 3) == bytes([0x40, 0x41, 0x42])
    assert target.log == [(b"\x40", 1), (b"\x41", 1), (b"\x42", 1)]
    assert aux.transfer(0x30, b"", 2) == bytes([0x43, 0x44])


def test_trigger_preserves_the_configured_dr_cfg() -> None:
    _, _, imu_emu, imu = seed_board()
    imu_emu.child_buses()["aux"].attach(0x30, Recorder())
    before = imu_emu.banks[0][0x13]
    imu.child_buses()["aux"].transfer(0x30, b"\x00", 1)
    assert imu_emu.banks[0][0x13] == before == imu.register_plan()[0x13]


def test_one_shot_data_is_not_there_before_the_transaction_completes() -> None:
    clock, spi, imu_emu, _ = seed_board()
    imu_emu.child_buses()["aux"].attach(0x1E, Hmc5883lEmulator(clock))
    for reg, value in ((0x08, 0x1E), (0x0B, 0x0B), (0x13, 0x31), (0x13, 0x01)):
        spi.transfer(0, bytes([reg, value]), 0)
    assert spi.transfer(0, b"\xcc", 1) != b"4"  # read at once: previous value
    clock.sleep(100e-6)
    assert spi.transfer(0, b"\xcc", 1) == b"4"


def _run(clock: SimulatedClock, drivers: list[Driver], seconds: float,
         schedule: dict[Driver, int], dithers: tuple[Dither, ...] = ()) -> list[Sample]:
    end = clock.now_ns() + round(seconds * 1e9)
    out: list[Sample] = []
    while True:
        driver = min(drivers, key=lambda d: schedule[d])
        if schedule[driver] > end:
            return out
        clock.sleep_until(schedule[driver])
        for dither in dithers:
            dither()
        result = driver.poll(clock.now_ns())
        out += result.samples
        schedule[driver] = result.next_poll_ns


def test_seed_board_reads_gyro_accel_and_mag_all_over_spi() -> None:
    clock, spi, imu_emu, imu = seed_board()
    mag_emu = imu_emu.child_buses()["aux"].attach(0x1E, Hmc5883lEmulator(clock))
    mag = Hmc5883lDriver(imu.child_buses()["aux"].link(0x1E), {}, device="mag", clock=clock)
    assert mag.probe().bus == "spi0/imu/aux"
    mag.configure()
    # level board at rest: +1 g specific force on the chip's Z (up), earth field tilted down
    # (values between counts, so the half-LSB dither moves every raw word as noise would)
    field = (21.0, -1.5, -43.0)
    rate = (0.0011, -0.0007, math.radians(10.03))
    force = (0.0123, -0.0071, 9.7913)
    imu_emu.set_physics(PhysicalInputs(angular_rate_rad_s=rate, specific_force_m_s2=force))
    mag_emu.set_physics(PhysicalInputs(magnetic_field_ut=field))
    now = clock.now_ns()
    schedule: dict[Driver, int] = {imu: imu.start(now), mag: mag.start(now)}
    samples = _run(clock, [imu, mag], 1.0, schedule, (Dither(imu_emu), Dither(mag_emu)))
    gyro = [s for s in samples if isinstance(s, GyroSample)]
    accel = [s for s in samples if isinstance(s, AccelSample)]
    mags = [s for s in samples if isinstance(s, MagSample)]
    assert all(s.valid for s in samples)
    # the HMC polls take ~1.4 ms of one-shot traffic each, so some IMU polls run late;
    # phase-locked polling still reads every 250 Hz sample before the next overwrites it
    assert len(gyro) >= 249 and len(accel) >= 249
    assert 70 <= len(mags) <= 75
    assert gyro[-1].gyro_rad_s == pytest.approx(rate, abs=math.radians(1 / 60))
    assert accel[-1].accel_m_s2 == pytest.approx(force, abs=9.80665 / 7500)
    assert mags[-1].mag_ut == pytest.approx(field, abs=100 / 1090)
    assert spi.kind is BusKind.SPI and {type(t) for t in spi.targets.values()} == {
        Max21100Emulator}
