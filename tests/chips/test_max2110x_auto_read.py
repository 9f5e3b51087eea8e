"""The HMC5883L read through the MAX21100's slave auto-read (``read: auto``), drivers against
emulators: the MAX21100 driver programs the auto-read and hands the slave's bytes of each
burst to the HMC5883L driver, which converts them and decides what is a new measurement.

The field values are chosen with three different axes and between counts, so a driver that
maps the axes or orders the bytes wrongly (the MAX21100's remap 0x08 or swap bit, the HMC's
X, Z, Y order) reads another field and fails."""

from __future__ import annotations

import bisect
import itertools
import math

import pytest
from tests.support.dither import Dither
from tests.support.master_slave import MasterSlaveBoard, valid_mag

from imuhal.bus.auto_read import AutoReadBus
from imuhal.bus.base import BusKind
from imuhal.core.clock import SimulatedClock
from imuhal.core.errors import ConfigurationError
from imuhal.core.samples import MagSample, Sample, SampleFlag
from imuhal.emulation import EmulatedBus, PhysicalInputs
from imuhal_chips.hmc5883l.driver import Hmc5883lDriver, unchanged_periods
from imuhal_chips.hmc5883l.emulator import Hmc5883lEmulator
from imuhal_chips.max2110x.driver import Max21100Driver
from imuhal_chips.max2110x.emulator import Max21100Emulator

FIELD_UT = (21.37, -7.73, -43.11)
"""Chip frame, uT: three different axes, none on a count at 1090 LSB/Ga (0.092 uT)."""
LSB_UT = 100 / 1090
PERIOD_NS = round(1e9 / 75)


class Board(MasterSlaveBoard):
    """The seed's board on a simulated clock: MAX21100 on SPI, HMC5883L behind its master."""

    def __init__(self, mag_settings: dict[str, object] | None = None) -> None:
        super().__init__()
        self.clock = SimulatedClock()
        self.spi = EmulatedBus("spi0", BusKind.SPI)
        self.imu_emu = self.spi.attach(0, Max21100Emulator(self.clock))
        self.mag_emu = self.imu_emu.child_buses()["aux"].attach(
            0x1E, Hmc5883lEmulator(self.clock))
        self.imu = Max21100Driver(self.spi.link(0), {"reset_check_s": 0.1}, device="imu",
                                  clock=self.clock)
        self.imu.probe()
        self.imu.configure()
        self.aux = self.imu.child_buses()["aux"]
        settings = {"read": "auto", **(mag_settings or {})}
        self.mag = Hmc5883lDriver(self.aux.link(0x1E), settings, device="mag",
                                  clock=self.clock)
        self.mag.probe()
        self.mag.configure()
        self.mag_emu.set_physics(PhysicalInputs(magnetic_field_ut=FIELD_UT))
        self.imu_emu.set_physics(PhysicalInputs(angular_rate_rad_s=(0.01, 0.02, 0.03),
                                                specific_force_m_s2=(0.1, 0.2, 9.7)))
        self.dithers = (Dither(self.mag_emu, seed=1), Dither(self.imu_emu, seed=2))


def test_the_field_comes_from_the_imu_burst_in_the_hmc5883l_axis_and_byte_order() -> None:
    board = Board({"reset_check_s": 60})
    board.run(0.2)
    aux_transfers, measured = board.aux.transfers, board.mag_emu.measurements
    samples = board.run(2.0)
    valid = valid_mag(samples)
    assert len(valid) >= 0.75 * 2.0 * 75 and len(valid) == len(samples)
    for s in valid:
        for axis in range(3):
            assert abs(s.mag_ut[axis] - FIELD_UT[axis]) <= 1.0001 * LSB_UT, (s, axis)
    # the mag's own transactions: status reads, at most one per measurement whose six
    # bytes equal the one's before (one in eight with this test's half-LSB dither, so
    # often two in a row, which make the driver doubt the copies for a while:
    # test_a_measurement_of_the_same_bytes_is_handed_out)
    changes = 1 + sum(a.mag_ut != b.mag_ut for a, b in itertools.pairwise(valid))
    reads = board.aux.transfers - aux_transfers
    assert 0 < reads <= board.mag_emu.measurements - measured - changes


def test_a_measurement_of_the_same_bytes_is_handed_out() -> None:
    """The chip measures B, A, A, B, A, B, B, ... (a field still to within a count, as 1 in
    500 of the seed's are): the master's copies of the second B do not change, and are no
    proof that nothing was measured. A copy made after the chip's next instant shows the
    same bytes, so the driver reads the status register once: RDY set, the chip measured,
    and that field is handed out a period after the one before. Every field the chip made
    comes out, in its order, and the driver's only transactions are those status reads."""
    board = Board({"reset_check_s": 60})
    board.dithers = board.dithers[1:]  # the magnetometer's field: this test's sequence
    other = (-FIELD_UT[0], -FIELD_UT[1], -FIELD_UT[2])

    def fly(sequence: str) -> tuple[list[tuple[float, float, float]], list[Sample]]:
        fields = [FIELD_UT if bit == "a" else other for bit in sequence]
        samples = []
        for field in fields:  # one measurement instant in each period stepped
            board.mag_emu.set_physics(PhysicalInputs(magnetic_field_ut=field))
            samples += board.run(PERIOD_NS / 1e9)
        return fields, samples

    fly("ba" * 8)  # settled, a field different from the one before each time
    aux_transfers = board.aux.transfers
    measured, samples = fly("baababbaab" * 4)
    samples += board.run(0.05)
    valid = valid_mag(samples)
    seen = [FIELD_UT if s.mag_ut[0] > 0 else other for s in valid]
    assert seen == measured
    assert all(b.t_ns - a.t_ns == PERIOD_NS for a, b in itertools.pairwise(valid))
    repeats = sum(a == b for a, b in itertools.pairwise(measured))
    # and one in the tail, where the chip measures the last field again (proved, held
    # until a change shows it was no late copy)
    assert board.aux.transfers - aux_transfers == repeats + 1


def test_the_max21100_keeps_the_slave_bytes_as_read() -> None:
    """har-in-air's registers (facts section 6, steps 1, 2, 4), except the map: 0x00 (as
    read) instead of 0x08, so the HMC5883L's driver gets its own register order."""
    board = Board()
    bank0 = board.imu_emu.banks[0]
    assert (bank0[0x06], bank0[0x08], bank0[0x09], bank0[0x0A], bank0[0x07]) == \
        (0x00, 0x1E, 0x03, 0x00, 0x86)


def test_samples_are_stamped_a_fixed_latency_after_each_measurement() -> None:
    """The master copies a measurement within one accelerometer period and the burst comes
    a guard later: the driver polls that long plus its own guard after each measurement
    instant (about 6 ms at the seed's rates) and stamps the poll's time."""
    board = Board()
    samples = valid_mag(board.run(1.0))
    latency = round(1e9 / 250) + round(1e9 / 250) // 8
    expected = latency + PERIOD_NS // 8
    origin = board.mag._mode_written_ns
    assert {(s.t_ns - origin) % PERIOD_NS for s in samples} == {expected}


def test_a_hung_max21100_tells_the_feed_that_its_bursts_copied_nothing() -> None:
    """The MAX21100 copies the slave at each accelerometer measurement. Its engine hung
    (data-ready never set), its driver still reads a burst at each poll and delivers the
    copy of before, saying that the master copied nothing since (the accelerometer's
    data-ready clear): the feed's copy time stays before the hang while its deliveries go
    on, until the driver's restart cures the chip (the HMC5883L proves a repeat only from
    a copy made after its chip's next instant)."""
    board = Board({"reset_check_s": 60})
    board.run(0.3)
    feed = board.aux.auto_read(0x1E, 0x03, 6)
    board.imu_emu.stuck_data_ready = True
    t_hung = board.clock.now_ns()
    board.run(0.015)
    assert board.imu.health.reconfigurations == 0  # not restarted yet
    assert feed.t_ns > t_hung + 10_000_000
    assert feed.copied_ns < t_hung


def test_a_stopped_magnetometer_is_flagged_stale_and_restarted() -> None:
    board = Board({"reset_check_s": 60})
    board.run(0.5)
    board.mag_emu.stuck_data_ready = True
    t_stuck = board.clock.now_ns()
    samples = board.run(0.5)
    stale = [s for s in samples if s.flags & SampleFlag.STALE]
    assert stale and all(math.isnan(s.mag_ut[0]) for s in stale)
    # flagged once the bytes stayed the same longer than the chip's noise allows ...
    limit = (unchanged_periods(1090) + 2.5) * PERIOD_NS
    assert stale[0].t_ns - t_stuck <= limit + 2 * PERIOD_NS
    # ... nothing valid until then, and the driver's restart (a Mode write) cures it
    assert not [s for s in valid_mag(samples) if t_stuck + PERIOD_NS < s.t_ns <= stale[-1].t_ns]
    assert board.mag.health.reconfigurations >= 1
    assert [s for s in valid_mag(samples) if s.t_ns > stale[-1].t_ns]


def test_a_slave_that_stops_answering_the_master_gives_no_valid_sample() -> None:
    """The MAX21100 keeps the last data when its read is not acknowledged: the same bytes
    arrive at every burst, which is not a new measurement; once they are overdue the
    driver's configuration check (one-shot reads: 0xFF) finds the chip gone and hands it to
    the recovery."""
    board = Board({"reset_check_s": 60})
    board.run(0.5)
    board.mag_emu.absent = True
    t_gone = board.clock.now_ns()
    samples = board.run(0.5)
    assert board.imu_emu.slave_read_failures > 0
    assert not [s for s in valid_mag(samples) if s.t_ns > t_gone + PERIOD_NS]
    assert board.errors > 0
    board.mag_emu.absent = False  # plugged back in: the driver's recovery brings it back
    assert valid_mag(board.run(0.5))


def test_a_copy_delayed_by_failed_slave_reads_is_still_handed_out() -> None:
    """A failed auto-read keeps the master's last copy; the measurement arrives with the next
    one, after the poll planned for it: the driver looks once more and does not lose it."""
    counts = []
    for failing in (False, True):
        board = Board({"reset_check_s": 60})
        board.run(0.3)
        if failing:  # every third transaction on the master's bus to the slave fails
            board.imu_emu.child_buses()["aux"].fail_transfers(set(range(1, 3000, 3)))
        valid = valid_mag(board.run(2.0))
        # fields that differ from the one before: a repeat is proved by a status read
        # through the master, which fails there too (test_a_measurement_of_the_same_...)
        counts.append(sum(a.mag_ut != b.mag_ut for a, b in itertools.pairwise(valid)))
    assert board.imu_emu.slave_read_failures > 150
    assert counts[1] >= counts[0] - 2


def test_frozen_conversions_are_flagged_frozen_once_they_outlast_the_frozen_rule() -> None:
    board = Board({"reset_check_s": 60})
    board.run(0.5)
    board.mag_emu.frozen = True
    samples = board.run(1.5)
    late = [s for s in samples if s.t_ns > board.clock.now_ns() - 500_000_000]
    assert late and not valid_mag(late)
    assert any(s.flags & SampleFlag.FROZEN for s in late)


def test_a_measurement_coming_back_after_a_master_reset_is_not_new() -> None:
    """A silent MAX21100 reset clears MAG X/Y/Z (blank) and stops the auto-read; once the
    IMU's driver has reprogrammed it, a stuck magnetometer's old bytes arrive again: they
    were handed out before, so they are not valid again."""
    board = Board({"reset_check_s": 60})
    board.run(0.5)
    board.mag_emu.frozen = True  # the same bytes at every measurement from now on
    board.run(0.05)
    reset_ns = board.clock.now_ns()
    board.imu_emu.silent_reset()
    reads = board.imu_emu.slave_reads
    samples = board.run(0.4)
    assert board.imu.health.resets_detected == 1
    assert board.imu_emu.slave_reads > reads  # the auto-read is back
    # (while the reset goes unnoticed the bytes read blank; the IMU's register check, one
    # register every reset_check_s / 12, may notice before the magnetometer polls)
    after = [s for s in samples if s.device == "mag" and s.t_ns > reset_ns]
    assert after and not valid_mag(after)


def test_the_first_measurement_after_configure_is_dropped() -> None:
    """It still uses the previous gain (HMC5883L datasheet): at +/-8.1 Ga after the
    default +/-1.3 Ga the first new bytes would read 4.7 times the field."""
    board = Board({"range_gauss": 8.1})
    samples = valid_mag(board.run(0.5))
    lsb = 100 / 230
    assert samples and all(abs(s.mag_ut[0] - FIELD_UT[0]) <= 1.0001 * lsb for s in samples)


def test_a_one_shot_transaction_with_another_slave_puts_the_auto_read_address_back() -> None:
    board = Board()
    board.aux.transfer(0x30, b"\x00", 1)  # nothing answers at 0x30: 0xFF
    assert board.imu_emu.banks[0][0x08] == 0x1E


def test_the_master_auto_reads_one_slave_of_at_most_six_bytes() -> None:
    board = Board()
    assert isinstance(board.aux, AutoReadBus)
    assert board.aux.auto_read(0x1E, 0x03, 6) is board.mag._feed
    with pytest.raises(ConfigurationError, match="already auto-reads 0x1E"):
        board.aux.auto_read(0x0C, 0x03, 6)
    with pytest.raises(ConfigurationError, match="7 bytes asked; the master keeps 1 to 6"):
        board.imu.enable_auto_read(0x1E, 0x03, 7)


def test_read_auto_on_a_bus_without_a_master_is_a_one_line_error() -> None:
    bus = EmulatedBus("i2c1", BusKind.I2C)
    bus.attach(0x1E, Hmc5883lEmulator())
    with pytest.raises(ConfigurationError, match=r"^hmc5883l 'mag' on i2c1 target 0x1E: "
                       r"read: auto needs .*; i2c1 cannot: use read: one-shot$"):
        Hmc5883lDriver(bus.link(0x1E), {"read": "auto"}, device="mag",
                       clock=SimulatedClock())


def test_unchanged_periods_grow_as_the_gain_makes_repeats_likelier() -> None:
    assert unchanged_periods(1090) == 5  # the seed's +/-1.3 Ga
    assert unchanged_periods(230) == 19  # +/-8.1 Ga, about 0.5 LSB of noise per axis


def _beside_fifo_reads(poll_plan: int | None = None, fifo_frames: int = 1, *,
                       imu_plan: int | None = None) -> Board:
    """The IMU read through its FIFO (issue 25) every ``fifo_frames`` periods, its clock
    2 % fast and the HMC5883L's 2 % slow, a field that moves a count a measurement (each
    one's bytes differ); the magnetometer on ``poll_plan``, the IMU on ``imu_plan`` (None:
    the newest)."""
    board = Board({"reset_check_s": 60})
    board.imu = Max21100Driver(board.spi.link(0), {"reset_check_s": 0.1, "read": "fifo",
                                                   "fifo_frames": fifo_frames},
                               device="imu", clock=board.clock)
    if imu_plan is not None:
        board.imu.poll_plan = imu_plan
    board.imu.configure()
    board.aux = board.imu.child_buses()["aux"]
    board.mag = Hmc5883lDriver(board.aux.link(0x1E), {"read": "auto", "reset_check_s": 60},
                               device="mag", clock=board.clock)
    if poll_plan is not None:
        board.mag.poll_plan = poll_plan
    board.mag.configure()
    board.imu_emu.oscillator_error = 0.02
    board.mag_emu.oscillator_error = -0.02
    emu = board.mag_emu
    emu.physics_source = lambda t_ns: emu.set_physics(PhysicalInputs(magnetic_field_ut=(
        FIELD_UT[0] + t_ns / PERIOD_NS * LSB_UT, FIELD_UT[1], FIELD_UT[2])))
    board.dithers = board.dithers[1:]
    return board


@pytest.mark.parametrize("fifo_frames", [1, 8])
def test_beside_fifo_reads_every_measurement_the_master_copied_is_handed_out(
        fifo_frames: int) -> None:
    """Beside FIFO reads (``_beside_fifo_reads``), every measurement the master copied
    reaches the HMC5883L's driver, also when two copies come between two of its polls,
    each stamped after its copy and in order. Read every 8 periods too: the master's copy
    is a register it overwrites at each of its measurements, so the driver reads it
    between its FIFO reads (before: about a third of the fields were lost)."""
    board = _beside_fifo_reads(fifo_frames=fifo_frames)
    emu = board.mag_emu
    board.run(0.5)
    first = emu.measured_ns[-1]
    samples = valid_mag(board.run(4.0))
    measured = [t for t in emu.measured_ns if t > first]
    latest_copy = board.clock.now_ns() - board.mag._feed.latency_ns
    expected = [t for t in measured if t < latest_copy]
    assert len(measured) >= len(samples) >= len(expected) > 280
    assert all(b.t_ns > a.t_ns for a, b in itertools.pairwise(samples))
    assert len({s.mag_ut[0] for s in samples}) == len(samples)


def test_beside_fifo_reads_the_magnetometer_looks_no_sooner_than_the_next_read() -> None:
    """Poll plan 2 (imuhal.core.poll_plan), the MAX21100 on it too (from plan 3 it reads
    the copies between its FIFO reads): a copy can come only with the master's next FIFO
    read, so the HMC5883L's driver is polled then, not at its own 75 Hz grid in between
    (plan 1: a poll that found nothing, then a retry). Read every 8 periods (32 ms, the
    seed board's FIFO benchmark): fewer polls, nearly none empty, the same measurements
    handed out (a stamp may differ within the copy's latency: a copy's stamp on the
    cadence is chosen against the poll that found it)."""
    fields, polls, empty = {}, {}, {}
    for plan in (1, 2):
        board = _beside_fifo_reads(plan, fifo_frames=8, imu_plan=2)
        samples = valid_mag(board.run(2.0))
        fields[plan] = [s.mag_ut for s in samples]
        polls[plan], empty[plan] = board.mag_polls, board.empty_mag_polls
        measured = board.mag_emu.measured_ns
        for s in samples:  # stamped after its measurement, within the copy's latency
            lag = s.t_ns - measured[bisect.bisect_left(measured, s.t_ns) - 1]
            assert 0 < lag <= board.mag._feed.latency_ns
    assert fields[2] == fields[1] and len(fields[2]) > 55
    assert empty[2] <= 2 < empty[1]
    assert polls[2] < polls[1]


def test_a_reconfiguration_while_the_master_auto_reads_leaves_no_field_torn() -> None:
    """Issue 25: the HMC5883L locks its data outputs from a partial data read until all six
    bytes are read (datasheet). A reconfiguration's one-shot read of the six bytes (a
    millisecond) straddling one of the master's copies (every accelerometer period) left
    the lock half released, and every later copy ended in the next measurement: X and Z
    of one, Y of the next, handed out as fields the chip never measured. Each measurement
    here moves all three axes by several counts, so a torn copy matches none of them."""
    board = Board({"reset_check_s": 60})
    emu = board.mag_emu
    fields: dict[int, tuple[float, float, float]] = {}

    def field_at(t_ns: int) -> None:
        k = round(t_ns / PERIOD_NS) % 40
        fields[t_ns] = (FIELD_UT[0] + 7 * k * LSB_UT, FIELD_UT[1] - 5 * k * LSB_UT,
                        FIELD_UT[2] + 3 * k * LSB_UT)
        emu.set_physics(PhysicalInputs(magnetic_field_ut=fields[t_ns]))

    emu.physics_source = field_at
    board.dithers = board.dithers[1:]
    board.run(0.2)
    samples: list[MagSample] = []
    for k in range(12):  # reconfigurations at phases spread over the copies' period
        board.clock.sleep(0.000_333 * k)
        board.schedule[board.mag] = board.mag.restart(reset_detected=False)
        samples += valid_mag(board.run(0.15))
    assert board.mag.health.reconfigurations == 12 and len(samples) > 100
    measured = set(fields.values())
    torn = [s.mag_ut for s in samples
            if not any(all(abs(s.mag_ut[i] - f[i]) <= 0.6 * LSB_UT for i in range(3))
                       for f in measured)]
    assert not torn


def test_a_copy_a_failed_slave_read_delayed_is_stamped_with_the_burst_that_brought_it() -> None:
    """The poll that looks again a delivery latency after the planned one stamps what it
    finds with the IMU burst that delivered it, not with itself: at most two accelerometer
    periods (the failed copy and the next) and the IMU's poll guard after the measurement,
    where the poll's own time lies up to 4.5 ms later still, past what the frame ledger's
    rounding of the field's period (13.3 ms) can absorb beside another delay."""
    board = Board({"reset_check_s": 60})
    board.run(0.3)
    board.imu_emu.child_buses()["aux"].fail_transfers(set(range(1, 3000, 3)))
    samples = valid_mag(board.run(2.0))
    measured = board.mag_emu.measured_ns
    accel_ns = round(1e9 / 250)
    ages = [s.t_ns - measured[bisect.bisect_right(measured, s.t_ns) - 1] for s in samples]
    assert board.imu_emu.slave_read_failures > 150 and len(samples) > 120
    assert max(ages) <= 2 * accel_ns + accel_ns // 8 + 200_000

