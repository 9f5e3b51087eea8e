"""The AK8963 read through the MPU-9250's slave 0 (``read: auto``), drivers against emulators:
the MPU-9250 driver programs I2C_SLV0 to read ST1..ST2 at every sample, carries
EXT_SENS_DATA in its own burst and hands the bytes to the AK8963 driver, which converts them
and decides from ST1.DRDY what is a new measurement.

The field has three different axes, none on a count, so a driver that swaps the bytes of a
word (little-endian HXL first), maps the axes wrongly or scales with the wrong resolution
reads another field and fails. Register numbers of the MPU-9250 in these tests are written
from the register map (rev 1.4), not imported from the driver."""

from __future__ import annotations

import bisect
import itertools
import math

import pytest
from tests.support.dither import Dither
from tests.support.master_slave import MasterSlaveBoard, valid_mag

from imuhal.bus.auto_read import AutoReadBus, AutoReadFeed
from imuhal.bus.base import BusKind
from imuhal.core.clock import SimulatedClock
from imuhal.core.errors import ConfigurationError
from imuhal.core.samples import SampleFlag
from imuhal.emulation import EmulatedBus, PhysicalInputs
from imuhal_chips.ak8963.driver import AK8963Driver
from imuhal_chips.ak8963.emulator import AK8963Emulator
from imuhal_chips.mpu9250.driver import MPU9250Driver
from imuhal_chips.mpu9250.emulator import MPU9250Emulator

FIELD_UT = (23.41, -17.93, 41.27)
"""AK8963 frame, uT: three different axes, none on a count (0.15 uT x ASA factor)."""
LSB_UT = 0.15 * 1.5  # the largest adjusted LSB (ASA 255)
TOLERANCE_UT = 3.0001 * LSB_UT
"""The dither's 2.5 LSB plus the chip's rounding."""
AK_PERIOD_NS = 10_000_000
I2C_MST_CTRL, I2C_SLV0_ADDR, I2C_SLV0_REG, I2C_SLV0_CTRL = 0x24, 0x25, 0x26, 0x27
I2C_MST_DELAY_CTRL, USER_CTRL = 0x67, 0x6A


class Board(MasterSlaveBoard):
    """An MPU-9250 (I2C or SPI, I2C master on) with its AK8963 read by slave 0."""

    def __init__(self, mag_settings: dict[str, object] | None = None, *,
                 kind: BusKind = BusKind.I2C, imu_settings: dict[str, object] | None = None,
                 ) -> None:
        super().__init__()
        self.clock = SimulatedClock()
        self.host = EmulatedBus("host", kind)
        address = 0x68 if kind is BusKind.I2C else 0
        self.imu_emu = self.host.attach(address, MPU9250Emulator(self.clock))
        self.mag_emu = self.imu_emu.child_buses()["aux"].attach(0x0C,
                                                                AK8963Emulator(self.clock))
        self.imu = MPU9250Driver(self.host.link(address),
                                 {"aux": "master", "reset_check_s": 60,
                                  **(imu_settings or {})},
                                 device="imu", clock=self.clock)
        self.imu.probe()
        self.imu.configure()
        self.aux = self.imu.child_buses()["aux"]
        self.mag = AK8963Driver(self.aux.link(0x0C),
                                {"read": "auto", "reset_check_s": 60, **(mag_settings or {})},
                                device="mag", clock=self.clock)
        self.mag.probe()
        self.mag.configure()
        self.mag_emu.set_physics(PhysicalInputs(magnetic_field_ut=FIELD_UT))
        self.imu_emu.set_physics(PhysicalInputs(angular_rate_rad_s=(0.01, 0.02, 0.03),
                                                specific_force_m_s2=(0.1, 0.2, 9.7)))
        # The field moves by up to 2.5 LSB at random, a real AK8963's noise (about 4 LSB at
        # 16 bits): under a half-LSB dither one measurement in eight would repeat the
        # previous one's bytes and be taken for a kept copy (see the driver's docstring).
        self.dithers = (Dither(self.mag_emu, seed=1, amplitude=2.49, spread=1.0),
                        Dither(self.imu_emu, seed=2))


@pytest.mark.parametrize("kind", [BusKind.I2C, BusKind.SPI])
def test_every_measurement_comes_from_the_mpu_burst_in_the_ak8963_byte_and_axis_order(
        kind: BusKind) -> None:
    board = Board(kind=kind)
    board.run(0.2)
    aux_transfers = board.aux.transfers
    samples = board.run(2.0)
    valid = valid_mag(samples)
    # 100 Hz, DRDY in ST1 marks each new copy; a measurement whose eight bytes equal the
    # previous one's is taken for the master's kept copy and not handed out (about one in
    # a hundred here)
    assert len(valid) >= 0.97 * 200 and len(valid) == len(samples)
    for s in valid:
        for axis in range(3):
            assert abs(s.mag_ut[axis] - FIELD_UT[axis]) <= TOLERANCE_UT, (s, axis)
    assert board.aux.transfers == aux_transfers  # no slave-4 transaction of the mag's own


def test_slave0_reads_st1_to_st2_as_read_at_every_sample() -> None:
    """I2C_SLV0_ADDR = RNW | 0x0C, _REG = ST1 (0x02), _CTRL = EN | 8 (no BYTE_SW: the
    AK8963's little-endian words reach its driver as the chip sends them), every sample
    (I2C_MST_DELAY_CTRL 0), data-ready after the copy (I2C_MST_CTRL.WAIT_FOR_ES)."""
    board = Board()
    regs = board.imu_emu._regs
    assert (regs[I2C_SLV0_ADDR], regs[I2C_SLV0_REG], regs[I2C_SLV0_CTRL]) == (0x8C, 0x02, 0x88)
    assert regs[I2C_MST_DELAY_CTRL] == 0 and regs[I2C_MST_CTRL] & 0x40
    assert regs[USER_CTRL] & 0x20


def test_samples_come_one_delivery_latency_after_each_measurement() -> None:
    """The MPU copies a measurement at its next sample (5 ms at 200 Hz) and the burst comes a
    guard later; the AK8963 driver polls then, so no sample is older than that."""
    board = Board()
    board.run(0.3)
    feed = board.mag._feed
    assert isinstance(feed, AutoReadFeed)
    assert feed.latency_ns == 5_000_000 + 5_000_000 // 8
    for s in valid_mag(board.run(1.0)):
        assert s.t_ns - feed.changed_ns < AK_PERIOD_NS
        # the latest measurement by the stamp, on the emulator's own clock (its record)
        measured = board.mag_emu.measured_ns
        age = s.t_ns - measured[measured.count_until(s.t_ns) - 1]
        assert age <= feed.latency_ns, age


def test_a_stopped_magnetometer_is_flagged_stale_never_valid_and_restarted() -> None:
    board = Board()
    board.run(0.5)
    board.mag_emu.stuck_data_ready = True
    t_stuck = board.clock.now_ns()
    samples = board.run(0.5)
    stale = [s for s in samples if s.flags & SampleFlag.STALE]
    assert stale and all(math.isnan(s.mag_ut[0]) for s in stale)
    assert stale[0].t_ns - t_stuck <= 4 * AK_PERIOD_NS  # the polling toolkit's 2.5 periods
    assert not [s for s in valid_mag(samples) if t_stuck + AK_PERIOD_NS < s.t_ns]
    assert board.mag.health.reconfigurations >= 1
    board.mag_emu.stuck_data_ready = False
    assert len(valid_mag(board.run(0.5))) >= 40


def test_a_slave_that_stops_answering_sets_slv0_nack_and_its_kept_copy_is_never_new() -> None:
    """The MPU keeps EXT_SENS_DATA when slave 0's read is not acknowledged: the last copy
    (DRDY set) arrives at every burst; it is not a new measurement."""
    board = Board()
    board.run(0.5)
    board.mag_emu.absent = True
    t_gone = board.clock.now_ns()
    board.clock.sleep(0.006)
    board.imu.poll(board.clock.now_ns())
    assert board.mag._feed is not None and board.mag._feed.failures  # SLV0_NACK read
    samples = board.run(0.5)
    assert not [s for s in valid_mag(samples) if s.t_ns > t_gone + AK_PERIOD_NS]
    assert board.errors > 0  # the overdue CNTL1 check finds nobody and recovery retries
    board.mag_emu.absent = False  # plugged back in: the recovery brings it back
    assert len(valid_mag(board.run(0.5))) >= 30


def test_a_copy_missed_by_failed_slave_reads_comes_with_the_next_read() -> None:
    """Every third slave-0 read fails: at 200 Hz the MPU reads each 100 Hz measurement at
    one of two samples, so nearly all still arrive, none twice."""
    counts = []
    for failing in (False, True):
        board = Board()
        board.run(0.3)
        if failing:
            board.imu_emu.child_buses()["aux"].fail_transfers(set(range(1, 3000, 3)))
        samples = board.run(2.0)
        assert len(valid_mag(samples)) == len(samples)
        counts.append(len(samples))
    # each measurement once at most (no kept copy handed out again), nearly all of them
    assert 0.9 * counts[0] <= counts[1] <= counts[0] <= 200


def test_each_failed_slave_read_reaches_the_feed_through_slv0_nack() -> None:
    """The MPU-9250 driver reads I2C_MST_STATUS (0x36) in its burst: each sample whose
    slave-0 read failed is delivered as a failed read, never as the slave's data."""
    board = Board()
    board.run(0.3)
    aux = board.imu_emu.child_buses()["aux"]
    first = aux.transfers
    aux.fail_transfers(set(range(1, 3000, 3)))
    board.run(2.0)
    reads = aux.transfers - first
    assert reads >= 400  # one slave-0 read a sample, no slave-4 transaction
    feed = board.mag._feed
    assert feed is not None and feed.failures == len(range(1, reads + 1, 3))


def test_a_copy_a_failed_slave_read_delayed_is_stamped_on_the_chips_cadence() -> None:
    """Issue 25: a failed read moves the copy one MPU sample (5 ms, half the field's
    period) later; SLV0_NACK tells the AK8963's driver so, and it stamps the copy where the
    failed read was, on its measurements' cadence: no field is older than the delivery
    latency at its stamp, as without failures, and the stamps step by whole periods
    (the frame ledger's count)."""
    board = Board()
    board.run(0.3)
    board.imu_emu.child_buses()["aux"].fail_transfers(set(range(1, 3000, 3)))
    samples = valid_mag(board.run(2.0))
    feed = board.mag._feed
    assert feed is not None and feed.failures > 100 and len(samples) > 150
    measured = board.mag_emu.measured_ns
    ages = [s.t_ns - measured[bisect.bisect_right(measured, s.t_ns) - 1] for s in samples]
    assert max(ages) <= feed.latency_ns
    steps = [(b.t_ns - a.t_ns) / AK_PERIOD_NS for a, b in itertools.pairwise(samples)]
    assert all(abs(step - round(step)) < 0.1 and round(step) >= 1 for step in steps)


def test_overflow_is_flagged_nevervalid_mag() -> None:
    board = Board()
    board.run(0.2)
    board.mag_emu.set_physics(PhysicalInputs(magnetic_field_ut=(3000.0, 2000.0, 100.0)))
    samples = [s for s in board.run(0.3) if s.t_ns > board.clock.now_ns() - 0.25e9]
    assert len(samples) >= 20 and not valid_mag(samples)
    assert all(s.flags & SampleFlag.OVERFLOW for s in samples)


def test_the_mpu_slower_than_the_ak8963_still_reads_each_sample_once() -> None:
    """At 50 Hz the MPU reads every other measurement (DOR set: one was overwritten);
    each copy is new, handed out once."""
    board = Board(imu_settings={"odr_hz": 50})
    board.run(0.3)
    valid = valid_mag(board.run(2.0))
    assert 0.95 * 100 <= len(valid) <= 101


def test_an_mpu_reset_restores_slave0_and_the_old_copy_is_not_new() -> None:
    board = Board()
    board.run(0.5)
    board.imu_emu.silent_reset()
    t_reset = board.clock.now_ns()
    samples = board.run(1.0)
    assert board.imu.health.resets_detected == 1
    assert board.imu_emu._regs[I2C_SLV0_CTRL] == 0x88
    after = valid_mag(samples)
    assert len(after) <= 101  # nothing handed out twice
    assert len([s for s in after if s.t_ns > t_reset + 0.5e9]) >= 45


def test_the_aux_bus_auto_reads_one_slave_of_at_most_fifteen_bytes() -> None:
    board = Board()
    assert isinstance(board.aux, AutoReadBus)
    assert board.aux.auto_read(0x0C, 0x02, 8) is board.mag._feed
    with pytest.raises(ConfigurationError, match="already auto-reads 0x0C"):
        board.aux.auto_read(0x0D, 0x02, 8)
    with pytest.raises(ConfigurationError, match="16 bytes asked; slave 0 reads 1 to 15"):
        board.imu.enable_auto_read(0x0C, 0x02, 16)


def test_read_auto_behind_the_bypass_is_a_one_line_error() -> None:
    clock = SimulatedClock()
    bus = EmulatedBus("i2c1", BusKind.I2C)
    mpu = bus.attach(0x68, MPU9250Emulator(clock))
    mpu.child_buses()["aux"].attach(0x0C, AK8963Emulator(clock))
    imu = MPU9250Driver(bus.link(0x68), {"aux": "bypass"}, device="imu", clock=clock)
    aux = imu.child_buses()["aux"]
    with pytest.raises(ConfigurationError, match=r"^ak8963 'mag' on i2c1 target 0x0C: "
                       r"read: auto needs .*set the MPU's aux: master$"):
        AK8963Driver(aux.link(0x0C), {"read": "auto"}, device="mag", clock=clock)
