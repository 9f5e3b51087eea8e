"""Issue 25 item 5: every frame accounted for. Each device of the gy91 board (MPU-9250,
AK8963 in bypass, BMP280: every emulator records its measurement instants) reports frames
produced, delivered and lost by cause; under each fault kind of the matrix the count within
each segment (a stretch between reconfigurations) equals the chip's own count of its
measurements over the segment's span, and delivered + lost = produced."""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml

from imuhal.core.samples import MagSample, PressureSample, Sample
from imuhal.emulation import open_emulated
from imuhal.emulation.faults import (
    AllZeros,
    BusErrors,
    BusOSError,
    ChipAbsent,
    ChipReset,
    CorruptTrim,
    FaultSpec,
    FrozenData,
    HostStall,
    LatePolls,
    StuckDataReady,
    TimingJitter,
)
from imuhal.pipeline import Pipeline
from imuhal.pipeline.accounting import CAUSES, FrameLedger
from imuhal.plugins.manager import Registry, load_registry
from imuhal.profile.bundled import bundled_profiles
from imuhal.profile.loader import load_profile, parse_profile, read_profile_text

DEVICES = ("imu", "mag", "baro")
SECONDS = 2.5

MATRIX: dict[str, tuple[list[FaultSpec], dict[str, str]]] = {
    # fault kind: (faults, a cause each named device must show)
    "none": ([], {}),
    "bus_errors": ([BusErrors(device=d, rate=0.03) for d in DEVICES], {}),
    "os_error": ([BusOSError(device=d, rate=0.03) for d in DEVICES], {}),
    "host_stall": ([LatePolls(device="imu", start_s=1.0, end_s=1.01, delay_s=0.2)],
                   {"imu": "host_stall", "mag": "host_stall"}),
    # stalls at every phase of each device's period (43.7 ms every 0.25 s): the devices
    # falling due inside one are polled more than half a period late (the BMP280 in forced
    # mode converts when triggered: its trigger slides, and the chip loses nothing)
    "host_stalls": ([HostStall(device="imu", start_s=0.6, end_s=2.3, every_s=0.25,
                               stall_s=0.0437)],
                    {"imu": "host_stall", "mag": "host_stall"}),
    "reset": ([ChipReset(device=d, start_s=1.0 + 0.3 * i) for i, d in enumerate(DEVICES)],
              {"imu": "reset", "mag": "reset"}),
    "frozen": ([FrozenData(device=d, start_s=1.0, end_s=1.6) for d in DEVICES],
               {"imu": "reset"}),
    "stuck": ([StuckDataReady(device=d, start_s=1.0, end_s=1.3) for d in DEVICES],
              {"imu": "reset", "mag": "reset"}),
    "absent": ([ChipAbsent(device=d, start_s=1.0, end_s=1.2) for d in DEVICES],
               {"imu": "reset", "mag": "reset", "baro": "reset"}),
    # polls late by up to 5 ms: by less than half a period they are made late and must
    # still read the sample due (the MPU-9250's and AK8963's polls sit within a guard after
    # their chip's instants); by more they are put off, and after PUT_OFF_AT_MOST made off
    # the grid, counted from the grid point before them
    "jitter": ([TimingJitter(device=d, start_s=1.0, end_s=1.6, max_delay_s=0.005)
                for d in DEVICES], {"imu": "host_stall"}),
    # every poll of the IMU 3 ms late (more than half its 5 ms period): put off three times,
    # then made 3 ms after a grid point
    "late_polls": ([LatePolls(device="imu", start_s=1.0, end_s=1.3, delay_s=0.003)],
                   {"imu": "host_stall"}),
}


@pytest.fixture(scope="module")
def registry() -> Registry:
    return load_registry()


def _run(registry: Registry, faults: list[FaultSpec]) -> Pipeline:
    profile = load_profile(bundled_profiles()["gy91.yaml"], registry)
    with open_emulated(profile, registry, seed=2, faults=faults, calibrated=False) as p:
        list(p.events(SECONDS))
    return p


def _ledger(p: Pipeline, device: str) -> FrameLedger:
    ledger = p.devices[device].ledger
    assert ledger is not None, f"{device} accounts for no stream"
    return ledger


def _fly(registry: Registry, board: str, faults: list[FaultSpec], seconds: float,
         edits: dict[str, str] | None = None) -> Pipeline:
    """A bundled board emulated (calibrated, seed 1, as the fault matrix flies it), its
    profile's text edited (each key replaced by its value) when ``edits`` says so."""
    path = bundled_profiles()[f"{board}.yaml"]
    text = read_profile_text(path)
    for old, new in (edits or {}).items():
        assert old in text, old
        text = text.replace(old, new)
    profile = parse_profile(text, str(path), registry)
    with open_emulated(profile, registry, seed=1, faults=faults) as p:
        list(p.events(seconds))
    return p


@pytest.fixture(scope="module")
def hung_gy91(registry: Registry) -> tuple[Pipeline, list[int]]:
    """gy91 flown 6 s with every chip hung for 90 ms from 5.455 s (``stuck_data_ready``, the
    fault matrix's window at 1 %, seed 1), and the stamps of its valid pressures."""
    faults: list[FaultSpec] = [StuckDataReady(device=d, start_s=5.455, end_s=5.545)
                               for d in DEVICES]
    profile = load_profile(bundled_profiles()["gy91.yaml"], registry)
    with open_emulated(profile, registry, seed=1, faults=faults) as p:
        stamps = [e.t_ns for e in p.events(6.0) if isinstance(e, PressureSample) and e.valid]
    return p, stamps


def _counts_as_the_chip(p: Pipeline, device: str) -> FrameLedger:
    """The device's ledger, each of its segments checked against the chip's own count."""
    ledger = _ledger(p, device)
    chip = p.board.emulators[device]
    segments = ledger.all_segments()
    assert [n for _, _, n in segments] == [chip.frames_between(a, b) for a, b, _ in segments]
    return ledger


@pytest.mark.parametrize("kind", sorted(MATRIX))
def test_each_segment_counts_the_frames_the_chip_measured(registry: Registry,
                                                          kind: str) -> None:
    faults, causes = MATRIX[kind]
    p = _run(registry, faults)
    for device in DEVICES:
        ledger = _ledger(p, device)
        chip = p.board.emulators[device]
        segments = ledger.all_segments()
        assert segments and ledger.delivered > 0
        measured = [chip.frames_between(first, last) for first, last, _ in segments]
        assert [n for _, _, n in segments] == measured, device
        assert ledger.delivered + sum(ledger.lost.values()) == ledger.produced
        if device in causes:
            assert ledger.lost[causes[device]] > 0, (device, dict(ledger.lost))


def test_without_faults_nothing_is_lost(registry: Registry) -> None:
    p = _run(registry, [])
    for device in DEVICES:
        assert not +_ledger(p, device).lost, device


def test_a_host_stall_is_charged_to_the_stall_and_not_missed(registry: Registry) -> None:
    """A 200 ms stall of a 200 Hz IMU: 40 frames overwritten before the host came back."""
    p = _run(registry, MATRIX["host_stall"][0])
    lost = _ledger(p, "imu").lost
    assert dict(lost) == {"host_stall": 40}


def test_the_first_field_after_blank_reads_is_read_on_the_poll_grid(
        registry: Registry) -> None:
    """Every chip reads 0x00 for 90 ms (the MPU-9250 recovers, holding the thread). The
    AK8963's driver retried a blank read a tenth of a period later, so the first field after
    the window was read wherever those retries had got to, up to a period after its
    measurement, and the gap before it counted one field more than the chip made; it now
    polls a blank chip on its grid."""
    blank: list[FaultSpec] = [AllZeros(device=d, start_s=5.455, end_s=5.545) for d in DEVICES]
    ledger = _counts_as_the_chip(_fly(registry, "gy91", blank, 6.0), "mag")
    assert ledger.lost["host_stall"] > 0


def test_the_run_summary_shows_each_devices_frames(registry: Registry) -> None:
    p = _run(registry, MATRIX["reset"][0])
    summary = p.summary()
    assert set(summary.frames) == set(DEVICES)
    imu = summary.frames["imu"]
    assert imu["produced"] == imu["delivered"] + sum(imu[f"lost_{c}"] for c in CAUSES)
    text = summary.describe()
    assert f"frames: produced {imu['produced']}, delivered {imu['delivered']}, lost " \
           f"{imu['lost_reset']} (reset {imu['lost_reset']})" in text


def test_delivered_frames_are_the_valid_samples_of_the_accounted_channel(
        registry: Registry) -> None:
    profile = load_profile(bundled_profiles()["gy91.yaml"], registry)
    with open_emulated(profile, registry, seed=2, faults=MATRIX["frozen"][0],
                       calibrated=False) as p:
        events = list(p.events(SECONDS))
    for device in DEVICES:
        ledger = _ledger(p, device)
        valid = sum(1 for e in events if isinstance(e, Sample) and e.device == device
                    and e.channel is ledger.channel and e.valid)
        assert ledger.delivered == valid, device


FIFO_MODES: dict[str, tuple[str, str]] = {
    # the imu read from its FIFO on a timer, and on every second data-ready edge
    "fifo": ("      read: fifo\n", ""),
    "fifo-on-edges": ("      read: fifo\n",
                      "    interrupt: {chip: gpiochip0, line: 17, edges_per_read: 2}\n"),
}


@pytest.mark.parametrize("mode", sorted(FIFO_MODES))
def test_fifo_modes_count_the_frames_the_chip_measured_through_stalls_overflows_and_resets(
        registry: Registry, tmp_path: Path, mode: str) -> None:
    settings, interrupt = FIFO_MODES[mode]
    text = bundled_profiles()["gy91.yaml"].read_text()
    text = text.replace("      aux: bypass\n", "      aux: bypass\n" + settings)
    path = tmp_path / "gy91.yaml"
    path.write_text(text.replace('    mount: "+X-Y-Z"\n', '    mount: "+X-Y-Z"\n' + interrupt, 1))
    faults = [HostStall(device="imu", start_s=0.8, stall_s=0.06, every_s=0.5),  # kept
              HostStall(device="imu", start_s=1.55, stall_s=0.3, every_s=10.0),  # overflows
              BusErrors(device="imu", rate=0.02), ChipReset(device="imu", start_s=2.1)]
    with open_emulated(load_profile(path, registry), registry, seed=2, faults=faults,
                       calibrated=False) as p:
        list(p.events(SECONDS))
    ledger = _ledger(p, "imu")
    chip = p.board.emulators["imu"]
    segments = ledger.all_segments()
    assert len(segments) >= 2  # the reset
    # stamped on the chip's clock: within microseconds of the instants, either side
    half = ledger.period_ns // 2
    assert [n for _, _, n in segments] == [
        sum(1 for t in chip.measured_ns if a - half < t < b + half) for a, b, _ in segments]
    assert ledger.delivered + sum(ledger.lost.values()) == ledger.produced
    # a FIFO keeps what a late read would cost: the losses are the overflow's and the reset's
    assert ledger.lost["fifo_overflow"] > 0 and ledger.lost["reset"] > 0
    assert ledger.lost["host_stall"] == 0


CHIP_TIMED: dict[str, tuple[str, str, str]] = {
    # stamped at the chip's instants: read from its FIFO on the chip's clock, or on its
    # data-ready line's edges (registers); the cause the stall's frames are lost to
    "fifo": ("      read: fifo\n", "", "fifo_overflow"),
    "data-ready": ("", "    interrupt: {chip: gpiochip0, line: 17}\n", "host_stall"),
}


@pytest.mark.parametrize("error", [0.02, -0.02])
@pytest.mark.parametrize("mode", sorted(CHIP_TIMED))
def test_a_long_stall_on_a_chip_two_percent_off_counts_the_frames_it_made(
        registry: Registry, tmp_path: Path, mode: str, error: float) -> None:
    # a 300 ms stall is 61.2 periods of a chip 2 % fast (58.8 slow): counted in nominal
    # periods its gap would be a frame short (long); in the period the chip's own stamps
    # show it is exact
    settings, interrupt, cause = CHIP_TIMED[mode]
    text = bundled_profiles()["gy91.yaml"].read_text()
    text = text.replace("      aux: bypass\n", "      aux: bypass\n" + settings)
    path = tmp_path / "gy91.yaml"
    path.write_text(text.replace('    mount: "+X-Y-Z"\n', '    mount: "+X-Y-Z"\n' + interrupt, 1))
    faults = [HostStall(device="imu", start_s=0.9, stall_s=0.3, every_s=10.0)]
    with open_emulated(load_profile(path, registry), registry, seed=1, faults=faults,
                       calibrated=False) as p:
        chip = p.board.emulators["imu"]
        chip.oscillator_error = error
        list(p.events(1.4))
    ledger = _ledger(p, "imu")
    assert ledger.lost[cause] > 40
    half = ledger.period_ns // 2
    assert [n for _, _, n in ledger.all_segments()] == [
        sum(1 for t in chip.measured_ns if a - half < t < b + half)
        for a, b, _ in ledger.all_segments()]


def test_a_hung_magnetometers_unmade_fields_are_counted_apart_from_lost_ones(
        hung_gy91: tuple[Pipeline, list[int]]) -> None:
    """Every chip of the board hangs for 90 ms (``stuck_data_ready``, the fault matrix's
    window at 1 %): the AK8963 (read directly) completes no measurement and DRDY stays
    clear, and the MPU-9250's restart holds the one thread for most of the hang, so the mag
    is not read until its chip measures again. Its reads that found nothing for 2.6 periods
    prove the hang; the fields it never made are counted ``not_measured``, neither produced
    nor lost, and the one its overrun bit (DOR) proves lost, so the ledger's count equals
    the chip's (it counted all thirteen lost before: 1000 for the chip's 988)."""
    p, _ = hung_gy91
    ledger = _counts_as_the_chip(p, "mag")
    assert ledger.not_measured >= 8  # 90 ms of a 100 Hz field, the hang ends at a read
    assert p.summary().frames["mag"]["not_measured"] == ledger.not_measured


def test_a_hang_begins_at_its_start_not_at_the_chips_next_access(registry: Registry) -> None:
    """The gy91 BMP280 hangs 9 ms from 0.4955 s and resets at 0.5 s (the fault matrix's
    ``reset + stuck_data_ready + frozen`` at 0.1 %): its measurement due at 0.4928 s, before
    the hang, is made, and the poll at 0.4958 s reads it as new. The hang used to begin at
    that poll, when the faults noticed it: the measurement was never made, the poll handed
    out the one before again as new, and the reset wiped the cycle before it could complete
    (498 frames for the chip's 497 in the matrix's 10 s)."""
    faults: list[FaultSpec] = [StuckDataReady(device="baro", start_s=0.4955, end_s=0.5045),
                               ChipReset(device="baro", start_s=0.5)]
    p = _fly(registry, "gy91", faults, 0.6)
    assert _counts_as_the_chip(p, "baro").lost["reset"] >= 1


def test_a_short_hang_of_the_max21100_is_proved_by_its_reads_that_found_nothing(
        registry: Registry) -> None:
    """The seed paraglider's MAX21100 hangs 9 ms (``stuck_data_ready``, the fault matrix's
    window at 0.1 %): two instants of its 4 ms period pass unmeasured. Its search polls, a
    guard apart, read its status with both data-ready bits clear for more than 1.5 periods
    after the latest frame, which proves the hang (``health.idle``); the slots are counted
    not measured (but the one its overrun bit proves lost), and the ledger equals the chip's
    count (it counted them lost before: 2500 for the chip's 2498 in the matrix's 10 s)."""
    p = _fly(registry, "seed-paraglider-vario",
             [StuckDataReady(device="imu", start_s=0.5, end_s=0.509)], 0.7)
    assert _counts_as_the_chip(p, "imu").not_measured >= 1


def test_a_stalled_host_does_not_make_a_measuring_magnetometer_hung(registry: Registry) -> None:
    """Host stalls at every phase of the AK8963's period while it measures on: every field
    the host missed is lost, none is counted as not measured."""
    p = _run(registry, MATRIX["host_stalls"][0])
    ledger = _ledger(p, "mag")
    assert ledger.lost["host_stall"] > 0 and ledger.not_measured == 0


def test_a_poll_made_off_its_grid_after_the_put_offs_is_counted_at_the_grid_point(
        registry: Registry) -> None:
    """Every poll of the seed rc board 10 ms late and up to 5 ms more for 90 ms, the MS5611's
    trim flipped four times (the fault matrix's ``corrupt_trim``, ``late_polls`` and
    ``jitter`` at 1 %, whole: the plan's faults order the jitter's draws): the MAX21105's
    poll, put off
    three times to grid points aimed a guard (P/8) later than its frames were stamped, is
    then made 2.5 ms after the grid point (of a 5 ms period), reading that point's sample.
    Counted from its stamp, 3.5 ms after the chip's instant where the frame before the
    stall was stamped 0.4 ms after its own, the gap rounded to one frame more than the chip
    made; it is counted at the grid point, however little later it comes."""
    faults: list[FaultSpec] = [
        *(CorruptTrim(device="baro", start_s=t, bits=1) for t in (2.125, 4.375, 6.625, 8.875)),
        *(LatePolls(device=d, start_s=5.455, end_s=5.545, delay_s=0.01) for d in DEVICES),
        *(TimingJitter(device=d, start_s=5.455, end_s=5.545, max_delay_s=0.005)
          for d in DEVICES)]
    ledger = _counts_as_the_chip(_fly(registry, "seed-rc-vario", faults, 6.0), "imu")
    assert ledger.lost["host_stall"] > 0


def test_a_copy_older_than_a_put_off_poll_aimed_at_is_stamped_by_its_delivery(
        registry: Registry) -> None:
    """Every poll of the seed paraglider board 10 ms late for 9 ms (the fault matrix's
    ``late_polls`` at 0.1 %): the HMC5883L's poll, put off a period, found the MAX21100's
    copy from before the stall (the master was late too, and the copy it aimed at came
    just after it). Stamped with the poll, a period after its measurement, it counted a
    field the chip never made; a copy older than a delivery latency and a guard at its poll
    is stamped by its delivery."""
    faults: list[FaultSpec] = [LatePolls(device=d, start_s=5.4955, end_s=5.5045, delay_s=0.01)
                               for d in DEVICES]
    ledger = _counts_as_the_chip(_fly(registry, "seed-paraglider-vario", faults, 6.0), "mag")
    assert ledger.delivered > 0.9 * 6.0 * 75


def test_a_poll_put_off_from_a_phase_search_aims_at_the_phase_of_the_frame_before(
        registry: Registry) -> None:
    """Host stalls of 20 ms, five a second (the fault matrix's ``host_stall`` at 10 %): the
    AK8963's poll after a field read on a put-off found nothing yet and searched a guard
    apart; the search point due at 7.8 ms after the chip's instant came 19 ms late and was
    put off to a guard after it, whole periods on, 9 ms after the chip's instant where the
    field before lay 1.5 ms after its own: the gap of 2.75 periods rounded to two fields
    lost for the chip's one. Put off a guard after the phase of the field before, and
    counted on it, the poll reads the next field 1.3 ms after its instant and counts it
    right (the MPU-9250's polls under ``jitter`` likewise)."""
    stalls: list[FaultSpec] = [HostStall(device=d, start_s=1.0, stall_s=0.02, rate_hz=5.0)
                               for d in DEVICES]
    p = _fly(registry, "gy91", stalls, 3.5)
    assert _counts_as_the_chip(p, "mag").lost["host_stall"] > 0


@pytest.mark.parametrize("error", [0.02, -0.02])
def test_gy91s_bmp280_counts_as_its_chip_on_a_clock_two_percent_off(
        registry: Registry, error: float) -> None:
    """The BMP280 has no data-ready bit and no conversion counter. In normal mode its
    oscillator paces the cycle and the poll grid ran on the nominal 20 ms: 2 % slow, it
    handed out every 50th output twice, stamped a cycle after the chip made it (999 for the
    chip's 979 in 20 s); 2 % fast, it lost every 50th unseen (999 for 1019). gy91's profile
    now triggers each conversion (forced mode, 40 Hz): one frame a trigger, whatever the
    oscillator does. Its barometer alone, 4 s: the ledger is the chip's count and every
    valid pressure carries a measurement of its own."""
    data = yaml.safe_load(bundled_profiles()["gy91.yaml"].read_text())
    data["devices"], data["estimators"] = {"baro": data["devices"]["baro"]}, {}
    profile = parse_profile(yaml.safe_dump(data), "gy91-baro.yaml", registry)
    with open_emulated(profile, registry, seed=1) as p:
        chip = p.board.emulators["baro"]
        chip.oscillator_error = error
        stamps = [s.t_ns for s in p.events(4.0) if isinstance(s, PressureSample) and s.valid]
    ledger = _counts_as_the_chip(p, "baro")
    assert ledger.delivered == ledger.produced == chip.frames_between(stamps[0], stamps[-1])
    carried = [chip.measured_ns.count_until(t) for t in stamps]
    assert carried == list(range(carried[0], carried[0] + len(stamps)))


def test_a_poll_read_after_its_put_offs_is_counted_on_the_phase_of_the_frame_before(
        registry: Registry) -> None:
    """Every poll of the gy91 AK8963 stalled 9 ms for 45 ms (a chain of host stalls, as the
    fault matrix's ``host_stall`` at 10 % makes with gy91's forced-mode BMP280 triggered at
    once after each): put off three times, the fourth attempt is read when it comes, 0.35
    ms after the chip's instant and 0.25 ms after a point of the phase the field before
    was counted on. It was counted at the point of the put-offs' grid before it, a guard
    after that phase, so a period early: the field it read, then the next one, read with
    nothing new between (``adjacent``), spanned a slot the ledger took for one the chip
    let pass (109 counted for the chip's 110). Counted on the phase itself, it is right."""
    stalls: list[FaultSpec] = [HostStall(device="mag", start_s=1.0, end_s=1.045,
                                         every_s=0.001, stall_s=0.009)]
    p = _fly(registry, "gy91", stalls, 1.1)
    assert _counts_as_the_chip(p, "mag").not_measured == 0


def test_a_field_counted_a_period_early_after_its_put_offs_is_put_back_by_the_next_ones_reads(
        registry: Registry) -> None:
    """20 ms host stalls at random, 5 a second from 1 s (the fault matrix's ``host_stall``
    at 10 %, seed 4; gy91's BMP280, triggered at once after each, makes chains of them):
    the AK8963's poll read after three put-offs comes at 1.8897 s, 1.3 ms after the chip's
    instant and 25 us before the point of the phase the field before was counted on, so
    it is counted at the point before, a period early. The driver's next reads find nothing
    new until the next field (``adjacent``): their stamps span no slot, so the slot its
    count spanned is a field the put-off count moved out of the gap before, lost to the
    stall there, not one the chip let pass (194 counted for the chip's 195, one "not
    measured", before)."""
    stalls: list[FaultSpec] = [HostStall(device=d, start_s=1.0, stall_s=0.02, rate_hz=5.0)
                               for d in DEVICES]
    profile = load_profile(bundled_profiles()["gy91.yaml"], registry)
    with open_emulated(profile, registry, seed=4, faults=stalls) as p:
        list(p.events(1.95))
    assert _counts_as_the_chip(p, "mag").not_measured == 0


def test_a_short_hang_of_the_rc_boards_hmc5883l_is_proved_by_rdy_left_clear(
        registry: Registry) -> None:
    """The seed rc board's HMC5883L (read directly) hangs 9 ms across one instant of its
    75 Hz output (``stuck_data_ready``, the fault matrix's window at 0.1 %). RDY is never
    cleared by a read (datasheet), so the first poll after the hang found RDY still set and
    handed out the field it had read a period before, stamped a period later (the ledger
    counted 51 fields for the chip's 50). The instant the chip let pass cleared RDY; the
    driver's reads find it clear until the next measurement, which proves the hang
    (``health.idle``): that slot is not measured, and the next field is read once."""
    p = _fly(registry, "seed-rc-vario",
             [StuckDataReady(device="mag", start_s=0.5, end_s=0.509)], 0.7,
             {"mode: single": "mode: continuous"})
    assert _counts_as_the_chip(p, "mag").not_measured == 1


@pytest.mark.parametrize("error", [-0.02, 0.02])
def test_the_rc_boards_hmc5883l_hands_out_each_field_it_measured_once_on_a_clock_2_percent_off(
        registry: Registry, error: float) -> None:
    """Read directly in continuous mode, the HMC5883L keeps RDY set, so its polls ran on
    the nominal period: a chip 2 % fast had a field in 50 overwritten unread and unseen, 2 %
    slow had one in 50 handed out twice, stamped a period later (issue 25: 30 of each in
    20 s). In single mode (the seed rc profile's ``mode: single``) the chip measures when
    the driver's Mode write starts it: every field the chip made is handed out once,
    stamped within the oscillator's error of the 6 ms measurement's end."""
    profile = load_profile(bundled_profiles()["seed-rc-vario.yaml"], registry)
    with open_emulated(profile, registry, seed=1, calibrated=False) as p:
        chip = p.board.emulators["mag"]
        chip.oscillator_error = error
        stamps = [s.t_ns for s in p.events(1.5)
                  if isinstance(s, MagSample) and s.device == "mag" and s.valid]
    ledger = _counts_as_the_chip(p, "mag")
    assert ledger.delivered == ledger.produced == len(stamps)
    off_ns = [min(abs(t - m) for m in chip.measured_ns) for t in stamps]
    assert max(off_ns) <= 6_000_000 / (1 - abs(error)) - 6_000_000 + 1  # 1 ns: rounding


def test_a_copy_after_a_stall_is_stamped_a_period_before_the_next_measurement(
        registry: Registry) -> None:
    """Host stalls of 20 ms, five a second, on every device of the seed paraglider (the
    fault matrix's ``host_stall`` at 10 %): after one, the MAX21100's registers held a copy
    made just before the HMC5883L's next instant, and the next delivery, 3.5 ms later in the
    same poll, held that next measurement. The cadence rule put the first copy two field
    periods after the field before, where the chip had made one (149 counted for its 148
    by 2 s); a change less than a period after a copy now bounds its stamp."""
    faults: list[FaultSpec] = [HostStall(device=d, start_s=1.0, stall_s=0.02, rate_hz=5.0)
                               for d in DEVICES]
    _counts_as_the_chip(_fly(registry, "seed-paraglider-vario", faults, 2.0), "mag")


@pytest.mark.parametrize("error", [0.02, -0.02])
def test_an_auto_read_magnetometer_off_its_nominal_clock_counts_the_fields_its_chip_made(
        registry: Registry, error: float) -> None:
    """The seed paraglider's HMC5883L behind the MAX21100's auto-read polled on a grid of its
    nominal period: 2 % fast, the grid fell behind the chip's instants until a poll's copy
    was older than a latency and a guard and was stamped at its delivery, 6 ms earlier after
    its measurement than the fields beside it; 2 % slow, the polls came before the copies and
    their looks again stamped them at delivery. The ledger rounds each gap to whole periods
    and counted fields lost that the chip never made (2.5 s: 202 for its 190 fast, 195 for
    its 182 slow; issue 25). Its grid now follows the chip's instants
    (``Hmc5883lDriver._steer``), and every field is delivered."""
    profile = load_profile(bundled_profiles()["seed-paraglider-vario.yaml"], registry)
    with open_emulated(profile, registry, seed=1) as p:
        p.board.emulators["mag"].oscillator_error = error
        list(p.events(SECONDS))
    ledger = _counts_as_the_chip(p, "mag")
    assert not +ledger.lost


def _fly_slow_magnetometer(registry: Registry, faults: list[FaultSpec], seconds: float,
                           edits: dict[str, str] | None = None,
                           poll_plan: int | None = None) -> Pipeline:
    """The seed paraglider (seed 1, as ``_fly``), its HMC5883L's oscillator 2 % slow and its
    MAX21100's 2 % fast (the stall tables' clocks), its profile's text edited by ``edits``,
    its drivers on ``poll_plan`` (default: the newest)."""
    path = bundled_profiles()["seed-paraglider-vario.yaml"]
    text = read_profile_text(path)
    for old, new in (edits or {}).items():
        assert old in text, old
        text = text.replace(old, new)
    profile = parse_profile(text, str(path), registry)
    with open_emulated(profile, registry, seed=1, faults=faults, poll_plan=poll_plan) as p:
        p.board.emulators["mag"].oscillator_error = -0.02
        p.board.emulators["imu"].oscillator_error = 0.02
        list(p.events(seconds))
    return p


def test_a_slow_magnetometers_read_back_waits_for_a_poll_that_takes_its_field(
        registry: Registry) -> None:
    """The HMC5883L 2 % slow behind the MAX21100's auto-read: its steered grid runs ahead of
    the chip's instants, and a periodic read-back of Config A through Mode made at a poll
    before a measurement locked the outputs; the measurement waited in the chip for the
    master's copy after the one that released the lock, was delivered 7.8 ms after it where
    the field before came 1.4 ms after its own, and the ledger rounded the gap to a field
    lost that the chip never skipped (``Hmc5883lDriver._read_back_now``; a read-back every
    20 ms here, where the bundled one comes once a second: 109 for the chip's 108)."""
    p = _fly_slow_magnetometer(registry, [], 1.5, edits={
        "      read: auto ": "      reset_check_s: 0.02\n      read: auto "})
    ledger = _counts_as_the_chip(p, "mag")
    assert not +ledger.lost


def test_a_slow_magnetometer_on_poll_plan_4_makes_its_read_backs_when_due(
        registry: Registry) -> None:
    """imuhal.core.poll_plan.READ_BACK_PLAN: the drivers replaying a plan-4 recording make
    the read-backs it recorded, at the first poll due, and so count the field the locked
    outputs delayed as lost, as they did (109 for the chip's 108; the test above: none)."""
    p = _fly_slow_magnetometer(registry, [], 1.5, edits={
        "      read: auto ": "      reset_check_s: 0.02\n      read: auto "}, poll_plan=4)
    ledger = _ledger(p, "mag")
    assert sum(ledger.lost.values()) == 1


def test_a_slow_auto_read_magnetometer_counts_its_fields_through_host_stalls(
        registry: Registry) -> None:
    """The HMC5883L 2 % slow behind the MAX21100's auto-read, the host stalled 20 ms twice a
    second: the put-off poll after a stall stamped the copy it took at its own time, 14 ms
    after its measurement on a grid that runs ahead of the slow chip, and the copy after
    it, left for the next grid point (the put-off poll skips its look again), was taken by
    the steer for a grid lagging the chip and stamped at the moved point, 8 to 10 ms after
    its measurement: gaps of 1.5 periods and more, fields counted lost that the chip never
    skipped (``Hmc5883lDriver._ahead``; 72 for the chip's 71)."""
    stalls: list[FaultSpec] = [HostStall(device="imu", start_s=0.5, every_s=0.5,
                                         stall_s=0.02)]
    p = _fly_slow_magnetometer(registry, stalls, 1.0)
    ledger = _counts_as_the_chip(p, "mag")
    assert ledger.lost["host_stall"] > 0 and ledger.lost["missed"] == 0


def test_a_max21100_polled_two_percent_fast_loses_no_frame(registry: Registry) -> None:
    """The seed paraglider's MAX21100 polled on its 1/64 early step: a chip 2 % fast never
    let a poll find nothing, so the grid fell behind it until a frame was overwritten
    unread, the overrun bit re-anchored the grid, and the search began again with the same
    step (2.5 s: 2 frames counted missed of its 636, issue 25). Its grid now doubles its
    shortfall as the MPU-9250's does (``PollGrid(catch_up=True)``) and learns the period."""
    profile = load_profile(bundled_profiles()["seed-paraglider-vario.yaml"], registry)
    with open_emulated(profile, registry, seed=1) as p:
        p.board.emulators["imu"].oscillator_error = 0.02
        list(p.events(SECONDS))
    ledger = _counts_as_the_chip(p, "imu")
    assert not +ledger.lost


def test_a_recording_of_poll_plan_3_keeps_its_polls_behind_a_chip_two_percent_fast(
        registry: Registry) -> None:
    """The MAX21100's catch-up moves its polls, and so its transfers, on a chip clock off
    its nominal period: it came with poll plan 4 (imuhal.core.poll_plan.CHIP_CLOCK_PLAN),
    so a drive on plan 3, as a replay of a recording made under it runs, polls as plan 3
    did: it falls behind a chip 2 % fast and counts the frames its overrun bits show
    missed (2 of 636 in 2.5 s), where plan 4 misses none (the test above)."""
    profile = load_profile(bundled_profiles()["seed-paraglider-vario.yaml"], registry)
    with open_emulated(profile, registry, seed=1, poll_plan=3) as p:
        p.board.emulators["imu"].oscillator_error = 0.02
        list(p.events(SECONDS))
    ledger = _counts_as_the_chip(p, "imu")
    assert ledger.lost["missed"] > 0


def test_a_phase_search_keeps_up_with_a_chip_clock_two_percent_fast(registry: Registry) -> None:
    """The MPU-9250's and AK8963's grids step 1/64 period short until they learn the chip's
    period from a poll that found nothing; a chip 2 % fast never let one find nothing, so
    the grid fell behind it and a frame was overwritten unread every ~240 periods, unseen
    by the stamps (gy91 IMU 1015 counted of 1019 in 5 s, issue 25). The grid now doubles its
    shortfall when a nominal clock would have shown it an empty poll by then."""
    profile = load_profile(bundled_profiles()["gy91.yaml"], registry)
    with open_emulated(profile, registry, seed=1, calibrated=False) as p:
        for name in ("imu", "mag"):
            p.board.emulators[name].oscillator_error = 0.02
        list(p.events(SECONDS))
    for name in ("imu", "mag"):
        _counts_as_the_chip(p, name)


def test_a_failed_forced_trigger_write_is_told_by_the_next_burst_not_a_recovery(
        registry: Registry) -> None:
    """gy91's BMP280 in forced mode: a trigger write that failed may or may not have started
    a conversion. The retry's burst tells (``measuring`` or the mode bits still forced:
    started at the write; asleep and idle: written again), so a bus error there costs no
    soft reset, NVM copy and trimming read (poll plan 3: 2 such recoveries in 3 s at 3 %
    bus errors on the barometer, 13 in 10 s), and every conversion is still counted."""
    p = _fly(registry, "gy91", [BusErrors(device="baro", rate=0.03)], 3.0)
    summary = p.summary()
    assert summary.bus_errors["baro"] > 0
    assert summary.driver["baro"]["reconfigurations"] == 0
    ledger = _counts_as_the_chip(p, "baro")
    assert ledger.delivered + sum(ledger.lost.values()) == ledger.produced



def test_a_conversion_a_hang_held_is_counted_once_and_never_stamped_valid_far_from_it(
        hung_gy91: tuple[Pipeline, list[int]]) -> None:
    """gy91's BMP280 in forced mode hangs with a conversion under way (the fault matrix's
    1 % window): reads find it ``measuring`` for 14 ms past its maximum time, then the
    MPU-9250's restart holds the one thread 111 ms, and the hang ends meanwhile. The
    conversion completes after the hang, and the read after the restart finds it done: it
    ended somewhere in those 111 ms, so it is STALE (counted lost), and the time it took
    is counted as slots not converted. Before, the emulator completed it at its own
    instant, inside the hang, when every read said ``measuring``, and the driver handed it
    out valid at the read 128 ms later, counting 5 frames lost the chip never made (the
    matrix: 400 for the chip's 395)."""
    p, stamps = hung_gy91
    ledger = _counts_as_the_chip(p, "baro")
    assert sum(ledger.lost.values()) == 1
    chip = p.board.emulators["baro"]
    instants = list(chip.measured_ns)
    late = [t - instants[chip.measured_ns.count_until(t) - 1] for t in stamps]
    assert max(late) <= ledger.period_ns
