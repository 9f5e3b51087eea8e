"""Issue 25: delivered + lost = produced against the chip's own count for streams stamped
with the host's poll, through the fault-injection interface (imuhal.emulation.faults).

Two causes the frame ledger used to count wrong on poll-stamped streams:

- the MAX21100 after a bus error: the poll after a failed one read the missed sample a
  period late, a gap the chip never had (the driver retries at once; the retry was taken
  back once because it made the slave auto-read's torn magnetometer copies show, whose
  cause was the HMC5883L driver's: the torn-copies test below);
- the MS5611, whose conversions the host starts: slots in which the host started none (its
  schedule slid after a late poll, another device's long recovery, a failed temperature
  read) were counted as frames lost; the chip never made them, so they are counted apart
  (``not_converted``), neither produced nor lost.

Each test checks, per segment of the ledger, its count against the emulator's record of
the chip's measurement instants (``ChipEmulator.frames_between``)."""

from __future__ import annotations

from pathlib import Path

import pytest

from imuhal.core.samples import Sample
from imuhal.emulation import open_emulated
from imuhal.emulation.faults import (
    AllOnes,
    AllZeros,
    BusErrors,
    BusOSError,
    ChipAbsent,
    ChipReset,
    FaultSpec,
    HostStall,
    StuckDataReady,
    TimingJitter,
)
from imuhal.pipeline import Pipeline
from imuhal.pipeline.accounting import FrameLedger
from imuhal.plugins.manager import Registry, load_registry
from imuhal.profile.bundled import bundled_profiles
from imuhal.profile.loader import load_profile

SECONDS = 4.0


@pytest.fixture(scope="module")
def registry() -> Registry:
    return load_registry()


def _fly(registry: Registry, board: str, faults: list[FaultSpec], seed: int = 3,
         seconds: float = SECONDS, poll_plan: int | None = None) -> Pipeline:
    profile = load_profile(bundled_profiles()[f"{board}.yaml"], registry)
    with open_emulated(profile, registry, seed=seed, faults=faults, calibrated=False,
                       poll_plan=poll_plan) as p:
        list(p.events(seconds))
    return p


def _failing_from_1_s(*, os_errors: bool = False) -> list[FaultSpec]:
    """The fault matrix's ``bus_errors`` at 10 % on every device of the seed paraglider
    from 1 s, and with ``os_errors`` its ``os_error`` at 10 % too."""
    devices = ("imu", "mag", "baro")
    faults: list[FaultSpec] = [BusErrors(device=d, rate=0.1, start_s=1.0) for d in devices]
    if os_errors:
        faults += [BusOSError(device=d, rate=0.1, start_s=1.0) for d in devices]
    return faults


def _ledger_matches_the_chip(p: Pipeline, device: str) -> FrameLedger:
    ledger = p.devices[device].ledger
    assert ledger is not None and ledger.delivered > 0
    chip = p.board.emulators[device]
    segments = ledger.all_segments()
    assert [n for _, _, n in segments] == \
        [chip.frames_between(first, last) for first, last, _ in segments], dict(ledger.lost)
    assert ledger.delivered + sum(ledger.lost.values()) == ledger.produced
    return ledger


def test_max21100_bus_errors_cost_no_frame_the_chip_kept(registry: Registry) -> None:
    p = _fly(registry, "seed-paraglider-vario", [BusErrors(device="imu", rate=0.03)])
    assert p.devices["imu"].bus_errors > 20
    ledger = _ledger_matches_the_chip(p, "imu")
    assert ledger.lost["bus_error"] == 0  # the retry read every sample a failed poll missed


def test_bus_errors_never_hand_out_more_magnetometer_fields_than_the_chip_measured(
        registry: Registry) -> None:
    """A torn copy of the slave auto-read (part of one measurement, part of the one before)
    is no field: at bus errors on the MAX21100 and its slave, the HMC5883L behind it hands
    out at most one valid field per measurement the chip made."""
    profile = load_profile(bundled_profiles()["seed-paraglider-vario.yaml"], registry)
    faults: list[FaultSpec] = [BusErrors(device=d, rate=0.01) for d in ("imu", "mag", "baro")]
    with open_emulated(profile, registry, seed=1, faults=faults, calibrated=False) as p:
        valid = [e.t_ns for e in p.events(10.0) if isinstance(e, Sample)
                 and e.device == "mag" and e.valid]
        measured = p.board.emulators["mag"].frames_between(0, valid[-1])
    assert 0 < len(valid) <= measured


@pytest.mark.parametrize("board", ["seed-gps-vario", "seed-paraglider-vario"])
def test_the_magnetometer_behind_a_master_counts_exactly_at_bus_errors(
        registry: Registry, board: str) -> None:
    """A failed slave read moves the master's copy a master sample later (half the AK8963's
    period behind the MPU-9250's slave 0): SLV0_NACK tells its driver, which stamps the
    copy on the chip's cadence (the MAX21100 reports none: its HMC5883L's stamps stay within
    the margin). A master that restarts (a failed burst it could not resume) delivers a copy
    that waited up to a field period in the slave: stamped on the cadence too. Not when
    that copy is a segment's first field (no cadence yet): then the check below, which
    takes a first stamp to carry the latest measurement, can differ by one (seed 3 at
    these rates; docs/acquisition.md)."""
    faults: list[FaultSpec] = [BusErrors(device=d, rate=0.02) for d in ("imu", "mag", "baro")]
    p = _fly(registry, board, faults, seed=1)
    ledger = _ledger_matches_the_chip(p, "mag")
    assert ledger.delivered > 0.9 * SECONDS * 75


def test_blank_reads_of_the_master_cost_its_slave_no_count(registry: Registry) -> None:
    """The MPU-9250 read blank for 90 ms, six times at other phases: no copy delivered, its
    recovery restarts slave 0, and the first copy after it holds a field up to a period old
    (ST1.DOR)."""
    windows: list[FaultSpec] = [AllZeros(device="imu", start_s=t, end_s=t + 0.09)
                                for t in (1.0, 1.5017, 2.0034, 2.5051, 3.0068, 3.5085)]
    p = _fly(registry, "seed-gps-vario", windows)
    assert p.devices["imu"].driver.health.reconfigurations >= 6
    _ledger_matches_the_chip(p, "mag")


def test_a_magnetometer_reconfigured_while_its_master_is_away_counts_exactly(
        registry: Registry) -> None:
    """The seed paraglider board's chips unplugged for 90 ms: the HMC5883L's driver
    reconfigures it while the MAX21100's auto-read is off, and reading Mode locks its
    outputs until the master's first copy, which then holds the bytes from before the
    reconfiguration: no field of it (it counted one the chip never made)."""
    p = _fly(registry, "seed-paraglider-vario",
             [ChipAbsent(device=d, start_s=5.455, end_s=5.545) for d in ("imu", "mag", "baro")],
             seed=1, seconds=6.0)
    assert p.devices["mag"].driver.health.reconfigurations >= 1
    _ledger_matches_the_chip(p, "mag")


def test_a_magnetometer_behind_a_stalled_master_charges_its_losses_to_the_stall(
        registry: Registry) -> None:
    """The seed paraglider board's host stalls 43.7 ms before an IMU poll every 0.25 s: the
    HMC5883L's copies the MAX21100 made meanwhile were overwritten unread. The HMC5883L's
    first poll after a stall hands out the copy from before it and then the copy after it;
    the stall noted at the poll belongs to the gap after the first (38 of 93 such frames
    were counted ``missed`` in 10 s). In these 2.5 s no two consecutive measurements are
    equal (which the master's copies of the data bytes cannot tell apart: ``missed``)."""
    stalls = HostStall(device="imu", start_s=1.0, end_s=2.5, every_s=0.25, stall_s=0.0437)
    p = _fly(registry, "seed-paraglider-vario", [stalls], seed=1, seconds=2.5)
    ledger = _ledger_matches_the_chip(p, "mag")
    assert ledger.lost["host_stall"] > 0
    assert ledger.lost["missed"] == 0, dict(ledger.lost)


def test_a_magnetometer_whose_master_resets_counts_exactly(registry: Registry) -> None:
    """The MAX21100 resets (a brown-out) every 0.41 s: its copies read blank and its
    auto-read stops until its driver notices; a configuration check of the HMC5883L
    meanwhile reads Mode and locks its outputs, so the master's first copy afterwards is a
    field from before the check: stamped no later than it, not as new (it put two fields
    between the same two measurements)."""
    resets: list[FaultSpec] = [ChipReset(device="imu", start_s=1.2045 + 0.4091 * k)
                               for k in range(10)]
    p = _fly(registry, "seed-paraglider-vario", resets, seed=1, seconds=5.5)
    assert p.devices["imu"].driver.health.resets_detected >= 10
    _ledger_matches_the_chip(p, "mag")


def test_a_hung_magnetometer_behind_a_master_is_proved_hung_by_the_masters_copies(
        registry: Registry) -> None:
    """Every chip of seed-gps-vario hangs for 90 ms (the fault matrix's ``stuck_data_ready``
    at 1 %): the MPU-9250's data-ready bit stays clear while it samples on, and each of
    its bursts whose sensor bytes moved carries slave 0's read of the AK8963 at that
    sample, ST1.DRDY clear 2.5 field periods on; the MPU's restart then holds the thread
    past the hang, and the first copy after it has DRDY and DOR. The AK8963's twelve
    unmade fields are counted ``not_measured`` and the one DOR proves lost: the chip's
    count (all thirteen were counted lost: 1000 for the chip's 988 in the matrix)."""
    p = _fly(registry, "seed-gps-vario",
             [StuckDataReady(device=d, start_s=5.455, end_s=5.545) for d in ("imu", "mag")],
             seed=1, seconds=6.0)
    ledger = _ledger_matches_the_chip(p, "mag")
    assert ledger.not_measured >= 8  # 90 ms of a 100 Hz field; the hang ends at a read


@pytest.mark.parametrize("start_s", [0.5, 0.5039])
def test_a_hang_of_one_field_behind_a_master_is_proved_by_the_copy_after_it(
        registry: Registry, start_s: float) -> None:
    """The AK8963 behind seed-gps-vario's slave 0 hangs 9 ms (the fault matrix's
    ``stuck_data_ready`` window at 0.1 %) and lets one measurement pass. Its quiet copies,
    dated a feed latency early, never reach 1.5 field periods after the field before, but
    they run unbroken up to the copy of its next field, whose ST1 has DOR clear: the chip
    measured once since that field (DOR is set by a measurement that overwrites one unread
    and cleared by every read), so the slot between is not measured, not lost (counted
    lost at seven of eight phases of the hang before: 70 for the chip's 69)."""
    p = _fly(registry, "seed-gps-vario",
             [StuckDataReady(device="mag", start_s=start_s, end_s=start_s + 0.009)],
             seed=1, seconds=0.7)
    ledger = _ledger_matches_the_chip(p, "mag")
    assert (ledger.not_measured, sum(ledger.lost.values())) == (1, 0)


def test_a_stalled_host_does_not_make_a_magnetometer_behind_a_master_hung(
        registry: Registry) -> None:
    """Host stalls of 20 ms, five a second (the fault matrix's ``host_stall`` at 10 %): the
    first copy after a stall can show ST1.DRDY clear although the AK8963 measured during
    it (slave 0's unseen reads in the stall took the measurement and cleared DRDY), so
    reads with DRDY clear prove nothing across a pause in the deliveries: no field is
    counted as not measured (two were, 997 for the chip's 999)."""
    p = _fly(registry, "seed-gps-vario",
             [HostStall(device=d, start_s=1.0, stall_s=0.02, rate_hz=5.0)
              for d in ("imu", "mag", "baro")], seed=1, seconds=10.0)
    ledger = _ledger_matches_the_chip(p, "mag")
    assert ledger.not_measured == 0 and ledger.lost["host_stall"] > 0


def test_a_magnetometer_keeps_its_fields_while_its_masters_data_ready_is_stuck(
        registry: Registry) -> None:
    """Only the MPU-9250's data-ready bit sticks (90 ms): the chip samples on and slave 0
    reads the AK8963 at every sample, so the two fields it copies before the MPU's driver
    restarts it (20 ms of stale samples) are handed out (they were lost), and none is
    counted as not measured."""
    profile = load_profile(bundled_profiles()["seed-gps-vario.yaml"], registry)
    stuck = StuckDataReady(device="imu", start_s=5.455, end_s=5.545)
    with open_emulated(profile, registry, seed=1, faults=[stuck], calibrated=False) as p:
        fields = [e.t_ns for e in p.events(6.0) if isinstance(e, Sample)
                  and e.device == "mag" and e.valid and 5.455e9 < e.t_ns < 5.545e9]
    ledger = _ledger_matches_the_chip(p, "mag")
    assert ledger.not_measured == 0
    assert p.devices["imu"].driver.health.reconfigurations >= 1  # the MPU's restart
    assert len(fields) == 2, fields


def test_a_hung_magnetometer_behind_the_max21100_is_proved_hung_by_its_status(
        registry: Registry) -> None:
    """Every chip of the seed paraglider board hangs for 90 ms (the fault matrix's
    ``stuck_data_ready`` at 1 %): the MAX21100's copies of the HMC5883L's six data bytes
    stay the same for 7.7 field periods, more than a measuring chip repeats them; its
    status register, read then, has RDY clear twice: the seven fields it never made are
    counted ``not_measured`` (they were counted lost: 748 for the chip's 741 in the
    matrix)."""
    p = _fly(registry, "seed-paraglider-vario",
             [StuckDataReady(device=d, start_s=5.455, end_s=5.545) for d in ("imu", "mag")],
             seed=1, seconds=6.0)
    ledger = _ledger_matches_the_chip(p, "mag")
    assert ledger.not_measured >= 5


@pytest.mark.parametrize("start_s", [0.505, 0.531])
def test_a_magnetometer_hung_with_its_max21100_is_proved_hung_not_repeated(
        registry: Registry, start_s: float) -> None:
    """The MAX21100 and the HMC5883L hang together (the fault matrix's ``stuck_data_ready``
    at 10 % hangs every chip of the board at once). The MAX21100's driver reads a burst at
    each poll until it restarts the chip, and says the master copied nothing (its
    accelerometer's data-ready clear): such bursts are no copy made after the HMC5883L's
    next instant, so its status read (RDY still set from its last measurement, which the
    master never copied) proves no repeat (at 0.531 s: 44 counted for the chip's 42);
    and while they come the driver reads the status again once the chip's second instant
    after its latest field is past, before the master's recovery holds the host: RDY
    clear, hung, and the copy of its last measurement after the master's restart ends the
    run with no slot counted lost (at 0.505 s: 42 for 40)."""
    p = _fly(registry, "seed-paraglider-vario",
             [StuckDataReady(device=d, start_s=start_s, end_s=start_s + 0.45)
              for d in ("imu", "mag")], seed=1, seconds=start_s + 0.25)
    ledger = _ledger_matches_the_chip(p, "mag")
    assert ledger.not_measured >= 1


def test_a_magnetometer_copy_after_a_pause_in_the_masters_deliveries_is_stamped_on_the_grid(
        registry: Registry) -> None:
    """The host's polls of every chip of the seed paraglider come up to 5 ms late for
    0.45 s (the fault matrix's ``jitter`` at 10 %), so the MAX21100's deliveries pause up
    to 30 ms. A copy after such a pause is stamped where a poll on time would have stamped
    its measurement (the HMC5883L driver's grid), not at its delivery or on the cadence of
    a field stamped off the grid: stamps up to a period after their measurement beside
    fields stamped a guard after theirs made the frame ledger count a field the chip never
    skipped (64 for the chip's 63 before)."""
    p = _fly(registry, "seed-paraglider-vario",
             [TimingJitter(device=d, max_delay_s=0.005, start_s=0.36, end_s=0.81)
              for d in ("imu", "mag", "baro")], seed=1, seconds=0.86)
    _ledger_matches_the_chip(p, "mag")


def test_a_magnetometer_copy_long_after_a_read_of_mode_holds_no_locked_outputs(
        registry: Registry) -> None:
    """The host's polls of every chip of the seed paraglider come up to 5 ms late from
    0.30 s: the HMC5883L's read-back of Mode (which locks its outputs until the master's
    next copy) at 0.529 s is followed by no delivery of the MAX21100's for 18 ms, in which
    its copies released the lock unseen; the copy delivered then holds the measurement of
    0.544 s, not the locked one, and dated at the read it lay before its measurement and
    the one before (59 for the chip's 58: ``Hmc5883lDriver._copied_since``)."""
    p = _fly(registry, "seed-paraglider-vario",
             [TimingJitter(device=d, max_delay_s=0.005, start_s=0.30, end_s=0.75)
              for d in ("imu", "mag", "baro")], seed=1, seconds=0.80)
    _ledger_matches_the_chip(p, "mag")


def test_a_magnetometer_copy_that_failed_reads_delayed_is_no_proved_repeat(
        registry: Registry) -> None:
    """Every device of the seed paraglider fails one transfer in ten from 1 s (the fault
    matrix's ``bus_errors`` at 10 %, seed 6). At 3.17 s two of the MAX21100's reads of the
    HMC5883L in a row fail, so its copies keep the field before past the chip's next
    instant and a status read (RDY set) proves a repeat; the late copy comes 8 ms after
    its measurement, past the first bound of ``_repeated``, and the chip's next
    measurement 4 ms after it. A change followed that soon is the measurement the repeat
    stood for: no repeat handed out (243 counted for the chip's 242 before)."""
    p = _fly(registry, "seed-paraglider-vario", _failing_from_1_s(), seed=6, seconds=3.2)
    _ledger_matches_the_chip(p, "mag")


def test_a_magnetometer_copy_taken_by_a_late_poll_is_stamped_where_a_poll_on_time_would(
        registry: Registry) -> None:
    """Every device of the seed paraglider fails one transfer in ten from 1 s (the fault
    matrix's ``bus_errors`` at 10 %, seed 7). At 3.55 s the HMC5883L's poll takes a copy
    delivered just more than a latency and a guard before it, stamped at its delivery,
    0.2 ms after its measurement; the next copy, delayed by failed master reads, is
    stamped 7 ms after its own: 20.1 ms apart, the ledger counted a field lost that the
    chip never skipped (269 for the chip's 268 before). Stamped at the grid point a poll
    on time would have taken it at, the gap is one period."""
    p = _fly(registry, "seed-paraglider-vario", _failing_from_1_s(), seed=7, seconds=3.58)
    _ledger_matches_the_chip(p, "mag")


def test_a_late_imu_poll_retried_after_a_bus_error_counts_exactly(
        registry: Registry) -> None:
    """Every device of the seed paraglider fails one transfer in ten with a bus error and
    one in ten with an OS error from 1 s (seed 7). At 2.79 s the MAX21100's poll, put off
    a period after the host held it, comes 1.7 ms late, fails on a bus error and is
    retried at once: the retry reads the frame the put-off poll was due for, and is
    counted from that poll's grid point (``FrameLedger.retried``); counted from its own
    stamp, 2.5 ms after its measurement, the gap rounded to a frame the chip never made
    (49 for the chip's 48 before)."""
    p = _fly(registry, "seed-paraglider-vario", _failing_from_1_s(os_errors=True),
             seed=7, seconds=2.8)
    _ledger_matches_the_chip(p, "imu")


def test_an_imu_retry_the_host_held_late_is_counted_on_the_phase_of_its_frame(
        registry: Registry) -> None:
    """Every device of the seed rc board fails one transfer in four from 0.4 s (seed 10).
    At 0.467 s the MAX21105's poll, 1.8 ms late, fails and is retried at once, but the
    host's one thread holds the retry 2.8 ms more: it reads the frame the failed poll was
    due for 4.6 ms after its instant, where the frame before lay 0.2 ms after its own.
    Counted from its stamp (1.9 periods) the gap held a frame the chip never made (the
    fault matrix's 10 % ``bus_errors``, seed 3: 2001 for the chip's 2000; here 103 for
    102); counted on the phase of the frame before (``Pipeline._count_late_retry``), it
    is the next one."""
    faults: list[FaultSpec] = [BusErrors(device=d, rate=0.25, start_s=0.4)
                               for d in ("imu", "mag", "baro")]
    p = _fly(registry, "seed-rc-vario", faults, seed=10, seconds=0.55)
    _ledger_matches_the_chip(p, "imu")


def test_a_late_retry_on_poll_plan_4_is_counted_at_its_stamp(registry: Registry) -> None:
    """imuhal.core.poll_plan.LATE_RETRY_PLAN: the count point moves where later put-off
    polls aim, so a replay of a plan-4 recording counts the retry at its stamp, as it was
    made (the flight above: 103 for the chip's 102)."""
    faults: list[FaultSpec] = [BusErrors(device=d, rate=0.25, start_s=0.4)
                               for d in ("imu", "mag", "baro")]
    p = _fly(registry, "seed-rc-vario", faults, seed=10, seconds=0.55, poll_plan=4)
    ledger = p.devices["imu"].ledger
    assert ledger is not None
    chip = p.board.emulators["imu"]
    assert sum(n for _, _, n in ledger.all_segments()) == sum(
        chip.frames_between(a, b) for a, b, _ in ledger.all_segments()) + 1


def test_a_magnetometer_copy_with_its_overrun_bit_after_failed_slave_reads_counts_exactly(
        registry: Registry) -> None:
    """I/O errors on the AK8963's wire behind the MPU-9250's slave 0, three in ten from
    0.5 s (seed 2). At 1.26 s a copy follows three failed slave reads with ST1.DOR set:
    the chip measured twice since the last good read, one field overwritten unread. It was
    placed on the chip's cadence one period after the field before (the failed read
    nearest it), 9.6 ms before its own measurement, and the ledger counted a field the
    chip never made (84 for 83). DOR now keeps it two periods on at least
    (``stamp_on_cadence(at_least=2)``) and proves a field lost before it, whatever the
    stamps say (``DeviceHealth.skipped_ns``): the seed GPS vario's 10 % ``bus_errors +
    os_error + all_ones`` at seed 2 counted 769 for the chip's 770, its first copy after
    a restart stamped at its delivery 6.8 ms after its measurement and the DOR copy 1.5
    periods after it."""
    p = _fly(registry, "seed-gps-vario", [BusOSError(device="mag", rate=0.3, start_s=0.5)],
             seed=2, seconds=0.9)
    _ledger_matches_the_chip(p, "mag")


def test_a_magnetometer_restart_broken_after_its_mode_write_ends_the_ledgers_segment(
        registry: Registry) -> None:
    """Every device of the seed paraglider fails one transfer in ten with a bus error and
    one in ten with an OS error from 1 s (the fault matrix's ``bus_errors+os_error+...``
    at 10 %). At 1.03 s a restart of the HMC5883L fails after its Mode write, which
    restarted the chip's measurements with a new phase; resumed as a glitch, the driver
    polled on the old grid and the ledger counted across the restart (89 for the chip's
    87 by 1.2 s). The configuration reads back as written, so the restart is completed:
    the grid re-anchored and a reconfiguration ends the ledger's segment."""
    p = _fly(registry, "seed-paraglider-vario", _failing_from_1_s(os_errors=True),
             seed=1, seconds=1.2)
    ledger = _ledger_matches_the_chip(p, "mag")
    assert len(ledger.all_segments()) == 2


@pytest.mark.parametrize("start_s", [0.5, 0.5067])
def test_a_hang_of_one_field_behind_the_max21100_is_proved_by_the_hmc5883ls_status(
        registry: Registry, start_s: float) -> None:
    """The HMC5883L behind the seed paraglider's MAX21100 hangs 9 ms (the fault matrix's
    ``stuck_data_ready`` window at 0.1 %) and lets one measurement pass. Once a copy made
    after its instant shows the same bytes, its status register has RDY clear before the
    next measurement could be writing: hung; the first copy after it is the chip's next
    measurement, so the slot between is not measured, not lost (58 counted for the chip's
    57 before, at either phase)."""
    p = _fly(registry, "seed-paraglider-vario",
             [StuckDataReady(device="mag", start_s=start_s, end_s=start_s + 0.009)],
             seed=1, seconds=0.8)
    ledger = _ledger_matches_the_chip(p, "mag")
    assert (ledger.not_measured, sum(ledger.lost.values())) == (1, 0)


def test_a_magnetometer_plugged_back_in_behind_a_paused_master_is_reconfigured_unused(
        registry: Registry) -> None:
    """Every chip of the seed paraglider board is unplugged for 9 ms (the fault matrix's
    ``absent`` at 0.1 %). The MAX21100 delivers no copy meanwhile, so none of the
    HMC5883L's zeros after power-up reaches its driver; the chip's one single-mode
    measurement at the power-on gain (the configured 1.3 Ga gain too) comes as a change
    after a status read found RDY clear. The configuration is read back first: the
    measurement is no field, the chip is reconfigured, and no slot it never measured is
    counted (52 counted for the chip's 51 before)."""
    p = _fly(registry, "seed-paraglider-vario",
             [ChipAbsent(device=d, start_s=0.6955, end_s=0.7045) for d in ("imu", "mag", "baro")],
             seed=1, seconds=1.1)
    ledger = _ledger_matches_the_chip(p, "mag")
    assert len(ledger.all_segments()) == 2  # reconfigured once


def test_a_reset_magnetometers_single_measurement_after_its_zeros_is_not_a_field(
        registry: Registry) -> None:
    """The HMC5883L behind the seed paraglider's MAX21100 resets at 0.5475 s: its data
    registers read 0, then it measures once in single mode. The master's copies bring a
    field and the zeros in one poll, the measurement in the next; that measurement is
    checked against the plan before it is handed out: no valid field between the reset and
    the reconfiguration (one stamped 0.564 s before, and the chip reconfigured 0.1 s
    later)."""
    reset_s = 0.5475
    p = _fly(registry, "seed-paraglider-vario", [ChipReset(device="mag", start_s=reset_s)],
             seed=1, seconds=0.85)
    ledger = _ledger_matches_the_chip(p, "mag")
    (_, before_reset_ns, _), (after_ns, _, _) = ledger.all_segments()
    assert before_reset_ns < reset_s * 1e9 < after_ns


def test_a_field_with_the_same_bytes_as_the_one_before_is_delivered_not_lost(
        registry: Registry) -> None:
    """No fault: the seed paraglider's HMC5883L measures the same six bytes twice in a row
    at 2.72 s (a field still to within a count). The MAX21100's copies do not change, and
    its status register, read once a copy made after the chip's instant has come, has RDY
    set: the chip measured, and the field is handed out (counted ``missed`` before)."""
    p = _fly(registry, "seed-paraglider-vario", [], seed=1, seconds=3.0)
    ledger = _ledger_matches_the_chip(p, "mag")
    assert sum(ledger.lost.values()) == 0
    assert p.devices["mag"].driver.health.reconfigurations == 0


def test_an_unplugged_magnetometer_behind_the_max21100_is_not_taken_for_a_hung_one(
        registry: Registry) -> None:
    """The HMC5883L unplugged for 80 ms while it measures on: the MAX21100's reads of it
    fail and keep the copy before, the same for as long as a hung chip's; its status
    register reads 0xFF (RDY set, the line released) or not at all, so its fields are
    lost, none is counted as not measured."""
    p = _fly(registry, "seed-paraglider-vario",
             [ChipAbsent(device="mag", start_s=5.45, end_s=5.53)], seed=1, seconds=6.0)
    ledger = _ledger_matches_the_chip(p, "mag")
    assert ledger.not_measured == 0 and sum(ledger.lost.values()) >= 5


def test_io_errors_on_the_aux_wire_are_slave_reads_the_master_reports(
        registry: Registry) -> None:
    """An I/O error on the magnetometer's line behind the MPU-9250's master is a failed
    slave-0 read (SLV0_NACK), not an error of the MPU-9250 on the host's bus."""
    p = _fly(registry, "seed-gps-vario", [BusOSError(device="mag", rate=0.03)])
    assert p.devices["imu"].bus_errors == 0
    _ledger_matches_the_chip(p, "mag")


def test_io_errors_on_the_aux_wire_count_exactly_from_the_fifo(registry: Registry,
                                                                tmp_path: Path) -> None:
    """The same through the MPU-9250's FIFO (``read: fifo``, the AK8963's bytes in every
    frame): SLV0_NACK covers a whole read, and a frame whose copy repeats the one before is
    taken as the failed slave read; a copy that a failed read moved a frame (half a field
    period) later was counted a field early (407 for the chip's 398 in 4 s)."""
    text = bundled_profiles()["seed-gps-vario.yaml"].read_text()
    path = tmp_path / "seed-gps-vario.yaml"
    path.write_text(text.replace("      aux: master\n", "      aux: master\n      read: fifo\n", 1))
    with open_emulated(load_profile(path, registry), registry, seed=1,
                       faults=[BusOSError(device="mag", rate=0.03)], calibrated=False) as p:
        list(p.events(SECONDS))
    assert p.devices["imu"].buffered  # the FIFO on the chip's clock
    _ledger_matches_the_chip(p, "mag")


def test_a_magnetometer_behind_fifo_reads_far_apart_loses_no_field(registry: Registry,
                                                                    tmp_path: Path) -> None:
    """The seed paraglider's MAX21100 read from its FIFO every 8 periods (32 ms), no fault:
    its copy of the HMC5883L is a register, not a FIFO entry, overwritten at each of its
    measurements, so the driver reads it a guard after each instant between its FIFO
    reads, as a register poll does. Every field is handed out and counted as the chip
    measured it (read only with the FIFO reads, 61 of the chip's 145 fields came out and
    the ledger counted 129 produced)."""
    text = bundled_profiles()["seed-paraglider-vario.yaml"].read_text()
    path = tmp_path / "seed-paraglider-vario.yaml"
    path.write_text(text.replace("      accel_odr_hz: 250\n",
                                 "      accel_odr_hz: 250\n      read: fifo\n"
                                 "      fifo_frames: 8\n", 1))
    with open_emulated(load_profile(path, registry), registry, seed=1,
                       calibrated=False) as p:
        list(p.events(2.0))
    assert p.devices["imu"].buffered  # the FIFO on the chip's clock
    ledger = _ledger_matches_the_chip(p, "mag")
    assert sum(ledger.lost.values()) == 0


@pytest.mark.parametrize(("faults", "skips"), [
    pytest.param([HostStall(device="baro", start_s=1.0, stall_s=0.1, every_s=0.5)], True,
                 id="host stalls"),
    # the MPU-9250 beside it on the SPI bus: its reset and reconfiguration hold the host
    pytest.param([ChipReset(device="imu", start_s=1.0 + 0.7 * i) for i in range(4)], True,
                 id="a neighbour's recoveries"),
    pytest.param([AllOnes(device="baro", start_s=1.5, end_s=1.6)], True, id="blank reads"),
    pytest.param([BusErrors(device=d, rate=0.03) for d in ("imu", "baro")], False,
                 id="bus errors"),
])
def test_ms5611_slots_never_converted_are_not_frames_lost(
        registry: Registry, faults: list[FaultSpec], skips: bool) -> None:
    p = _fly(registry, "seed-gps-vario", faults)
    ledger = _ledger_matches_the_chip(p, "baro")
    assert (ledger.not_converted > 0) is skips


def test_the_run_summary_shows_the_slots_not_converted(registry: Registry) -> None:
    p = _fly(registry, "seed-gps-vario",
             [HostStall(device="baro", start_s=1.0, stall_s=0.1, every_s=1.0)])
    baro = p.summary().frames["baro"]
    assert baro["not_converted"] > 0
    assert "slots not converted" in p.summary().describe()
