"""HMC5883L emulator bus face: pointer, lock, RDY, modes and gain latency (datasheet Rev E)."""

from __future__ import annotations

import pytest

from imuhal.bus.base import BusKind
from imuhal.core.clock import SimulatedClock
from imuhal.core.samples import Quantity
from imuhal.emulation import EmulatedBus, PhysicalInputs
from imuhal.emulation.faults import BoardFaults, StuckDataReady
from imuhal_chips.hmc5883l.decode import data_counts_xyz
from imuhal_chips.hmc5883l.emulator import Hmc5883lEmulator

A = 0x1E


def rig() -> tuple[SimulatedClock, EmulatedBus, Hmc5883lEmulator]:
    clock = SimulatedClock()
    bus = EmulatedBus("i2c1", BusKind.I2C)
    emu = bus.attach(A, Hmc5883lEmulator(clock))
    return clock, bus, emu


def continuous(bus: EmulatedBus, clock: SimulatedClock, cra: int = 0x18, crb: int = 0x20,
               ) -> None:
    """CRA (default 75 Hz, 1 average), CRB, continuous mode; wait for one measurement."""
    bus.transfer(A, bytes([0x00, cra, crb, 0x00]), 0)
    clock.sleep(0.014)


def stuck_data_ready_at_100_ms(end_s: float) -> tuple[
        SimulatedClock, EmulatedBus, Hmc5883lEmulator, BoardFaults]:
    """A chip in continuous mode at 75 Hz whose StuckDataReady runs from 0.1 s to
    ``end_s``, the clock at its start and the fault applied."""
    clock, bus, emu = rig()
    faults = BoardFaults(clock, {"mag": emu}, faults=[
        StuckDataReady(device="mag", start_s=0.1, end_s=end_s)])
    continuous(bus, clock)
    clock.sleep_until(100_000_000)
    faults.sync()
    return clock, bus, emu, faults


def test_power_on_defaults_and_identity() -> None:
    _, bus, _ = rig()
    assert bus.transfer(A, b"\x00", 3) == bytes([0x10, 0x20, 0x01])
    assert bus.transfer(A, b"\x0a", 3) == b"H43"


def test_undefined_bits_and_read_only_registers_ignore_writes() -> None:
    _, bus, _ = rig()
    bus.transfer(A, b"\x00\xff\xff", 0)
    assert bus.transfer(A, b"\x00", 2) == bytes([0x7F, 0xE0])
    bus.transfer(A, b"\x0a\x00", 0)
    assert bus.transfer(A, b"\x0a", 1) == b"H"
    assert bus.transfer(A, b"\x20", 1) == b"\x00"  # invalid address reads 0


def test_pointer_wraps_from_register_8_back_to_3() -> None:
    clock, bus, emu = rig()
    emu.set_physics(PhysicalInputs(magnetic_field_ut=(10.0, 20.0, 30.0)))
    continuous(bus, clock)
    block = bus.transfer(A, b"\x03", 8)
    assert block[6:8] == block[0:2]  # after Y_LSB the pointer is at X_MSB again
    # the pointer now sits at Z_MSB: a bare read continues Z, Y, then wraps to X again
    assert bus.transfer(A, b"", 6) == block[2:6] + block[0:2]


def test_data_registers_hold_x_z_y() -> None:
    clock, bus, emu = rig()
    emu.set_physics(PhysicalInputs(magnetic_field_ut=(10.0, -20.0, 30.0)))
    continuous(bus, clock)
    x, y, z = data_counts_xyz(bus.transfer(A, b"\x03", 6))
    k = emu.resolution(Quantity.MAG)
    assert (x * k, y * k, z * k) == pytest.approx((10.0, -20.0, 30.0), abs=k)
    assert bus.transfer(A, b"\x05", 2) == z.to_bytes(2, "big", signed=True)


def test_partial_read_locks_outputs_until_all_six_bytes_are_read() -> None:
    clock, bus, emu = rig()
    emu.set_physics(PhysicalInputs(magnetic_field_ut=(10.0, 0.0, 0.0)))
    continuous(bus, clock)
    first_x_msb = bus.transfer(A, b"\x03", 1)
    assert bus.transfer(A, b"\x09", 1)[0] & 0x02  # LOCK
    emu.set_physics(PhysicalInputs(magnetic_field_ut=(50.0, 0.0, 0.0)))
    clock.sleep(0.014)  # a new measurement completes while locked
    rest = bus.transfer(A, b"\x04", 5)
    x = int.from_bytes(first_x_msb + rest[:1], "big", signed=True)
    assert x * emu.resolution(Quantity.MAG) == pytest.approx(10.0, abs=0.1)
    assert bus.transfer(A, b"\x09", 1)[0] & 0x02 == 0
    x_new = data_counts_xyz(bus.transfer(A, b"\x03", 6))[0]
    assert x_new * emu.resolution(Quantity.MAG) == pytest.approx(50.0, abs=0.1)


def test_reading_the_mode_register_locks_the_outputs() -> None:
    clock, bus, _ = rig()
    continuous(bus, clock)
    bus.transfer(A, b"\x02", 1)
    assert bus.transfer(A, b"\x09", 1)[0] & 0x02


def test_rdy_is_set_by_a_measurement_and_not_cleared_by_reading() -> None:
    clock, bus, _ = rig()
    bus.transfer(A, bytes([0x00, 0x18, 0x20, 0x00]), 0)
    assert bus.transfer(A, b"\x09", 1)[0] & 0x01 == 0
    clock.sleep(1 / 75)
    assert bus.transfer(A, b"\x09", 1)[0] & 0x01
    bus.transfer(A, b"\x03", 6)
    assert bus.transfer(A, b"\x09", 1)[0] & 0x01


def test_continuous_mode_measures_at_the_output_rate() -> None:
    clock, bus, emu = rig()
    bus.transfer(A, bytes([0x00, 0x14, 0x20, 0x00]), 0)  # 30 Hz
    for _ in range(100):
        clock.sleep(0.01)
        bus.transfer(A, b"\x03", 6)
    assert emu.measurements == 30


def test_single_mode_measures_once_then_shows_idle() -> None:
    clock, bus, emu = rig()
    clock.sleep(0.01)  # the power-on single measurement
    bus.transfer(A, b"\x02\x01", 0)
    clock.sleep(0.0059)
    assert bus.transfer(A, b"\x09", 1)[0] & 0x01 == 1  # from power-on
    clock.sleep(0.01)
    bus.transfer(A, b"\x03", 6)
    assert emu.measurements == 2
    assert bus.transfer(A, b"\x02", 1)[0] & 0x03 == 0b11


def test_first_measurement_after_a_gain_change_uses_the_old_gain() -> None:
    clock, bus, emu = rig()
    emu.set_physics(PhysicalInputs(magnetic_field_ut=(40.0, 0.0, 0.0)))
    bus.transfer(A, bytes([0x00, 0x18, 0x80, 0x00]), 0)  # gain 440 from default 1090
    clock.sleep(1 / 75)
    assert data_counts_xyz(bus.transfer(A, b"\x03", 6))[0] == round(0.4 * 1090)
    clock.sleep(1 / 75)
    assert data_counts_xyz(bus.transfer(A, b"\x03", 6))[0] == round(0.4 * 440)


def test_field_beyond_the_adc_range_reads_minus_4096_on_that_axis_only() -> None:
    clock, bus, emu = rig()
    emu.set_physics(PhysicalInputs(magnetic_field_ut=(250.0, 10.0, -300.0)))
    continuous(bus, clock)
    x, y, z = data_counts_xyz(bus.transfer(A, b"\x03", 6))
    assert (x, z) == (-4096, -4096) and y == round(0.1 * 1090)


def test_silent_reset_restores_defaults_and_stuck_fault_clears_on_mode_write() -> None:
    clock, bus, emu = rig()
    continuous(bus, clock)
    emu.stuck_data_ready = True
    clock.sleep(1 / 75)  # the hung chip lets an instant pass: RDY clear
    assert bus.transfer(A, b"\x09", 1)[0] & 0x01 == 0
    bus.transfer(A, b"\x02\x00", 0)
    clock.sleep(1 / 75)
    assert bus.transfer(A, b"\x09", 1)[0] & 0x01
    emu.silent_reset()
    assert bus.transfer(A, b"\x00", 3) == bytes([0x10, 0x20, 0x01])


def test_after_stuck_data_ready_ends_the_chip_measures_on_its_cadence_nothing_inside() -> None:
    """No measurement completes while StuckDataReady lasts; when it ends without a Mode
    write, the next comes on the chip's own cadence (1 / 75 Hz from the Mode write). A chip
    that completed the one it owed at the first read after the fault would hand out a
    field dated inside the fault, up to a period later than a measurement can be read."""
    clock, bus, emu, faults = stuck_data_ready_at_100_ms(end_s=0.3)
    period_ns = round(1e9 / 75)
    bus.transfer(A, b"\x03", 6)
    before = list(emu.measured_ns)  # all that fell due before the fault
    assert len(before) == 100_000_000 // period_ns
    clock.sleep_until(300_000_000)
    faults.sync()
    bus.transfer(A, b"\x03", 6)  # the first read after the fault: nothing new
    assert list(emu.measured_ns) == before
    clock.sleep(period_ns / 1e9)
    bus.transfer(A, b"\x03", 6)
    (first_after,) = list(emu.measured_ns)[len(before):]
    assert first_after >= 300_000_000 and (first_after - before[0]) % period_ns == 0


def test_a_reset_chip_measures_once_at_its_power_on_gain_then_idles_with_rdy_set() -> None:
    """What the driver must not take for new fields (issue 26): after a reset the chip is in
    single mode (its default), measures once at the default gain (1090 LSB/Ga), shows idle
    and keeps RDY and those bytes however often they are read."""
    clock, bus, emu = rig()
    emu.set_physics(PhysicalInputs(magnetic_field_ut=(40.0, 0.0, 0.0)))
    continuous(bus, clock, crb=0xE0)  # 230 LSB/Ga
    emu.silent_reset()
    clock.sleep(0.01)
    frames = []
    for _ in range(10):
        assert bus.transfer(A, b"\x09", 1)[0] & 0x01
        frames.append(bus.transfer(A, b"\x03", 6))
        clock.sleep(1 / 75)
    assert set(frames) == {frames[0]} and data_counts_xyz(frames[0])[0] == round(0.4 * 1090)
    assert bus.transfer(A, b"\x02", 1)[0] & 0x03 == 0b11


def test_only_i2c_is_accepted() -> None:
    from imuhal.core.errors import BusError

    emu = Hmc5883lEmulator()
    with pytest.raises(BusError, match="only an I2C"):
        emu.bus_transfer(BusKind.SPI, b"\x0a", 3)


def test_reading_the_data_never_clears_rdy() -> None:
    """The datasheet clears RDY only when the chip starts writing new data: a host that
    reads the data and then the status again before the next measurement finds RDY set."""
    clock, bus, _ = rig()
    continuous(bus, clock)
    bus.transfer(A, b"\x03", 6)
    assert bus.transfer(A, b"\x09", 1)[0] & 0x01


def test_a_hang_that_lets_an_instant_pass_leaves_rdy_clear_until_the_next_measurement(
) -> None:
    """stuck_data_ready for 9 ms across one instant (the fault matrix's 0.1 % window): the
    instant the chip lets pass clears RDY, and RDY stays clear after the fault ends until
    the chip measures again on its own cadence, so a read between finds no data ready
    rather than the field it already read."""
    clock, bus, _, faults = stuck_data_ready_at_100_ms(end_s=0.109)
    period_ns = round(1e9 / 75)
    assert bus.transfer(A, b"\x09", 1)[0] & 0x01  # no instant passed yet
    clock.sleep_until(110_000_000)
    faults.sync()  # the fault is over; the instant at 106.7 ms passed unmeasured
    assert bus.transfer(A, b"\x09", 1)[0] & 0x01 == 0
    clock.sleep_until(9 * period_ns - 1)
    assert bus.transfer(A, b"\x09", 1)[0] & 0x01 == 0
    clock.sleep_until(9 * period_ns)
    assert bus.transfer(A, b"\x09", 1)[0] & 0x01
