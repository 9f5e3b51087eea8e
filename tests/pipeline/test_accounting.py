"""FrameLedger: frames counted from the chip's period, losses charged to their cause."""

from __future__ import annotations

import pytest

from imuhal.core.blocks import Block
from imuhal.core.samples import GyroSample, MagSample, Quantity, SampleFlag
from imuhal.pipeline.accounting import FrameLedger, describe_frames

P = 5_000_000  # 200 Hz


def gyro(t_ns: int, flags: SampleFlag = SampleFlag.OK) -> GyroSample:
    return GyroSample(t_ns=t_ns, device="imu", flags=flags, gyro_rad_s=(0.0, 0.0, 0.0))


def test_frames_a_period_apart_lose_nothing() -> None:
    ledger = FrameLedger(Quantity.GYRO, P)
    for k in range(10):
        ledger.observe(gyro(1_000_000 + k * P + (k % 3) * 100_000))  # poll jitter < P/2
    assert (ledger.produced, ledger.delivered, sum(ledger.lost.values())) == (10, 10, 0)


def test_a_gap_of_four_periods_is_three_lost_frames_charged_to_the_cause_seen() -> None:
    ledger = FrameLedger(Quantity.GYRO, P)
    ledger.observe(gyro(0))
    ledger.note("bus_error")
    ledger.observe(gyro(4 * P))
    assert dict(ledger.lost) == {"bus_error": 3}
    assert ledger.produced == 5


def test_the_weightiest_cause_takes_the_gap_and_causes_clear_after_a_frame() -> None:
    ledger = FrameLedger(Quantity.GYRO, P)
    ledger.observe(gyro(0))
    ledger.note("bus_error")
    ledger.note("host_stall")
    ledger.observe(gyro(3 * P))
    ledger.observe(gyro(6 * P))  # nothing seen in between: the grid missed them
    assert dict(ledger.lost) == {"host_stall": 2, "missed": 2}


def test_a_cause_noted_with_its_start_waits_for_the_gap_that_spans_it() -> None:
    """A late poll notes the stall from its due time; a frame stamped before that (an
    auto-read copy the master brought before the stall) closes a gap without it."""
    ledger = FrameLedger(Quantity.GYRO, P)
    ledger.observe(gyro(0))
    ledger.note("host_stall", at_ns=3 * P // 2)
    ledger.observe(gyro(P))  # from before the stall: no loss, the stall still to come
    ledger.observe(gyro(4 * P))
    assert dict(ledger.lost) == {"host_stall": 2}


def test_a_timed_cause_spanned_by_a_gapless_block_is_spent() -> None:
    ledger = FrameLedger(Quantity.GYRO, P)
    ledger.observe(gyro(0))
    ledger.note("host_stall", at_ns=P // 2)
    ledger.observe_block(Block.from_samples([gyro(k * P) for k in (1, 2, 3)]))
    ledger.observe(gyro(6 * P))
    assert dict(ledger.lost) == {"missed": 2}


def test_a_frame_read_off_the_grid_is_counted_from_its_grid_point() -> None:
    """Polls a guard after the chip's instants; one made 3.6 ms (of 5) after its grid point
    reads that point's frame: from its stamp the gaps would round to 2 frames and then 0."""
    ledger = FrameLedger(Quantity.GYRO, P)
    ledger.observe(gyro(600_000))
    ledger.count_at(P + 4_200_000, P + 600_000)
    ledger.observe(gyro(P + 4_200_000))
    ledger.observe(gyro(2 * P + 600_000))
    assert ledger.produced == 3 and not ledger.lost


def test_a_late_poll_retried_after_a_bus_error_is_counted_from_its_grid_point() -> None:
    """The late poll of the test above fails on a bus error and its driver retries it at
    once, 1 ns later: the retry reads the frame the failed poll was due for, counted from
    the failed poll's grid point, not from its own stamp."""
    ledger = FrameLedger(Quantity.GYRO, P)
    ledger.observe(gyro(600_000))
    ledger.count_at(P + 4_200_000, P + 600_000)
    ledger.note("bus_error")
    ledger.retried(P + 4_200_000)
    ledger.observe(gyro(P + 4_200_001))
    ledger.observe(gyro(2 * P + 600_000))
    assert ledger.produced == 3 and not ledger.lost


def test_a_poll_later_than_a_guard_after_a_failed_late_one_is_counted_from_its_stamp() -> None:
    """No retry at once: a frame stamped more than a guard after the failed late poll is
    another read's, counted from its stamp."""
    ledger = FrameLedger(Quantity.GYRO, P)
    ledger.observe(gyro(600_000))
    ledger.count_at(P + 600_000, P + 100_000)
    ledger.retried(P + 600_000)
    ledger.observe(gyro(2 * P + 600_000))
    assert ledger.produced == 3 and ledger.lost["missed"] == 1


def test_a_late_retry_counted_on_its_frames_phase_is_counted_from_its_stamp_if_it_skipped(
        ) -> None:
    """A late retry is counted at the phase point before its stamp only while the chip's
    next instant had not come (``count_at(unless_skipped=True)``): its read found a frame
    overwritten unread, so it read a later frame, and its stamp counts it."""
    ledger = FrameLedger(Quantity.GYRO, P)
    ledger.observe(gyro(600_000))
    ledger.count_at(2 * P + 10_000, P + 600_000, unless_skipped=True)
    ledger.skipped(2 * P + 10_000)
    ledger.observe(gyro(2 * P + 10_000))
    ledger.observe(gyro(3 * P + 500_000))
    assert ledger.produced == 4 and ledger.lost["missed"] == 1


def test_a_late_retry_that_skipped_nothing_is_counted_on_its_frames_phase() -> None:
    ledger = FrameLedger(Quantity.GYRO, P)
    ledger.observe(gyro(600_000))
    ledger.count_at(P + 4_900_000, P + 600_000, unless_skipped=True)
    ledger.observe(gyro(P + 4_900_000))
    ledger.observe(gyro(2 * P + 500_000))
    assert ledger.produced == 3 and not ledger.lost


def test_flagged_frames_of_the_stream_name_their_cause() -> None:
    ledger = FrameLedger(Quantity.GYRO, P)
    ledger.observe(gyro(0))
    ledger.observe(gyro(P, SampleFlag.FROZEN))
    ledger.observe(gyro(2 * P))
    ledger.observe(gyro(3 * P, SampleFlag.STALE))
    ledger.observe(gyro(4 * P))
    assert dict(ledger.lost) == {"flagged": 1, "stale": 1}
    assert ledger.delivered == 3


def test_other_channels_do_not_count() -> None:
    ledger = FrameLedger(Quantity.GYRO, P)
    ledger.observe(MagSample(t_ns=0, device="imu", mag_ut=(1.0, 0.0, 0.0)))
    assert ledger.produced == 0 and ledger.first_ns is None


def test_a_reset_closes_a_segment_and_its_gap_is_lost_to_the_reset() -> None:
    ledger = FrameLedger(Quantity.GYRO, P)
    ledger.observe(gyro(0))
    ledger.observe(gyro(P))
    ledger.note("reset")
    ledger.observe(gyro(30 * P + 1_000_000))
    ledger.observe(gyro(31 * P + 1_000_000))
    assert ledger.all_segments() == [(0, P, 2), (30 * P + 1_000_000, 31 * P + 1_000_000, 2)]
    assert dict(ledger.lost) == {"reset": 28}  # 29.2 periods from P to 30 P + 1 ms
    assert ledger.produced == 32


def test_an_unknown_cause_is_refused() -> None:
    with pytest.raises(ValueError, match="unknown loss cause 'gremlins'"):
        FrameLedger(Quantity.GYRO, P).note("gremlins")


def test_the_summary_line_names_each_cause() -> None:
    ledger = FrameLedger(Quantity.GYRO, P)
    ledger.observe(gyro(0))
    ledger.note("host_stall")
    ledger.observe(gyro(3 * P))
    assert describe_frames(ledger.counts()) == \
        "produced 4, delivered 2, lost 2 (host stall 2)"


def test_slots_a_host_paced_chip_never_converted_are_neither_produced_nor_lost() -> None:
    """The MS5611's schedule slid 3.4 periods after a late poll: the gap of 5.4 periods
    holds one frame the chip made and the host did not deliver, and 3 slots it never
    converted (the chip's own count: delivered + lost)."""
    ledger = FrameLedger(Quantity.GYRO, P)
    ledger.observe(gyro(0))
    ledger.note("host_stall")
    ledger.slid(3 * P + 2 * P // 5)
    ledger.observe(gyro(5 * P + 2 * P // 5))
    assert dict(ledger.lost) == {"host_stall": 1}
    assert (ledger.produced, ledger.delivered, ledger.not_converted) == (3, 2, 3)
    assert ledger.counts()["not_converted"] == 3


def test_a_gap_of_slots_never_converted_is_a_gap_of_its_own_cause() -> None:
    ledger = FrameLedger(Quantity.GYRO, P)
    ledger.observe(gyro(0))
    ledger.slid(2 * P)
    loss = ledger.observe(gyro(3 * P))
    assert loss is not None and (loss.frames, loss.cause) == (2, "not_converted")
    assert not ledger.lost and ledger.produced == 2


def test_a_slide_within_half_a_period_costs_no_slot() -> None:
    ledger = FrameLedger(Quantity.GYRO, P)
    ledger.observe(gyro(0))
    ledger.slid(P // 3)
    assert ledger.observe(gyro(P + P // 3)) is None
    ledger.observe(gyro(2 * P + P // 3))  # the slide was forgotten at the frame after it
    assert (ledger.produced, ledger.not_converted) == (3, 0)


def test_the_summary_line_names_the_slots_not_converted() -> None:
    counts = {"produced": 10, "delivered": 9, "lost_bus_error": 1, "not_converted": 4}
    assert describe_frames(counts) == \
        "produced 10, delivered 9, lost 1 (bus error 1); slots not converted 4"


def test_slots_a_hung_chip_let_pass_are_not_measured_but_one_overrun_is_lost() -> None:
    """Reads found nothing new for two periods after the frame at 0 (the chip hung); the
    read at 14 periods brings a frame with the overrun bit set: of the 13 slots between, the
    chip made the one overwritten (lost) and none of the other 12."""
    ledger = FrameLedger(Quantity.GYRO, P)
    ledger.observe(gyro(0))
    ledger.idle(0, 2 * P + P // 2)
    ledger.note("host_stall")
    ledger.overrun(14 * P)
    loss = ledger.observe(gyro(14 * P))
    assert dict(+ledger.lost) == {"host_stall": 1}
    assert (ledger.produced, ledger.delivered, ledger.not_measured) == (3, 2, 12)
    assert loss is not None and (loss.frames, loss.cause) == (13, "host_stall")
    assert ledger.counts()["not_measured"] == 12


def test_an_overrun_a_period_after_the_frame_before_is_one_lost_frame() -> None:
    """A poll grid that drifted past an instant reads the frame after it one period after
    the one before: the stamps show no gap, the chip's overrun bit shows the frame between."""
    ledger = FrameLedger(Quantity.GYRO, P)
    ledger.observe(gyro(0))
    ledger.skipped(P + P // 50)
    ledger.observe(gyro(P + P // 50))
    assert (ledger.produced, ledger.delivered, dict(ledger.lost)) == (3, 2, {"missed": 1})


def test_an_overrun_found_by_a_segments_first_read_is_lost_to_the_reset_before_it() -> None:
    """The first read after a reconfiguration finds the overrun bit set (the chip measured
    twice before it): the frame it overwrote belongs to the gap that ends the old segment,
    lost to the reset, and the new segment starts at the frame read, as the chip's own
    count from that frame does."""
    ledger = FrameLedger(Quantity.GYRO, P)
    ledger.observe(gyro(0))
    ledger.note("reset")
    first = P + P // 5  # the stamps alone show no slot between
    ledger.skipped(first)
    ledger.observe(gyro(first))
    ledger.observe(gyro(first + P))
    assert ledger.all_segments() == [(0, 0, 1), (first, first + P, 2)]
    assert dict(+ledger.lost) == {"reset": 1} and ledger.produced == 4


def test_a_hung_chip_without_an_overrun_made_only_the_frame_read() -> None:
    ledger = FrameLedger(Quantity.GYRO, P)
    ledger.observe(gyro(0))
    ledger.idle(0, 3 * P)
    loss = ledger.observe(gyro(6 * P))
    assert loss is not None and (loss.frames, loss.cause) == (5, "not_measured")
    assert (ledger.produced, ledger.not_measured, sum(ledger.lost.values())) == (2, 5, 0)


def test_a_frame_read_as_the_chips_next_measurement_has_no_slot_lost_before_it() -> None:
    """The read of the frame at 2 periods proved the chip measured once since the frame at
    0 (``adjacent``: unbroken reads that found nothing, then DRDY without DOR): the slot
    the stamps span is one a hang too short for ``idle`` let pass, not measured."""
    ledger = FrameLedger(Quantity.GYRO, P)
    ledger.observe(gyro(0))
    ledger.adjacent(0, 2 * P)
    loss = ledger.observe(gyro(2 * P))
    assert loss is not None and (loss.frames, loss.cause) == (1, "not_measured")
    assert (ledger.produced, ledger.not_measured, sum(ledger.lost.values())) == (2, 1, 0)


def test_a_frame_counted_a_period_early_is_put_back_by_the_next_frames_adjacent_reads(
        ) -> None:
    """A frame read after a stall at 10.95 periods (past the chip's instant, just before a
    point of its phase) and counted at the point before (``count_at``, 10 periods): the
    next frame's reads prove nothing new since it (``adjacent``) and their stamps lie a
    period apart, so the slot its count spanned was a frame the count moved out of the gap
    before, lost to the stall there, not one the chip let pass."""
    ledger = FrameLedger(Quantity.GYRO, P)
    ledger.observe(gyro(0))
    ledger.note("host_stall")
    early = 11 * P - P // 100
    ledger.count_at(early, 10 * P)
    ledger.observe(gyro(early))
    ledger.adjacent(early, 12 * P)
    loss = ledger.observe(gyro(12 * P))
    assert loss is not None and (loss.frames, loss.cause) == (1, "host_stall")
    assert (ledger.produced, dict(ledger.lost), ledger.not_measured) == (
        13, {"host_stall": 10}, 0)


@pytest.mark.parametrize("since, overrun, note", [
    (-P, False, ""),  # proved after another frame than the latest valid one
    (0, True, ""),  # the overrun bit says a measurement was overwritten: lost
    (0, False, "reset"),  # the chip reconfigured between: its segment ends
])
def test_a_proof_of_the_next_measurement_counts_only_for_the_frame_before(
        since: int, overrun: bool, note: str) -> None:
    ledger = FrameLedger(Quantity.GYRO, P)
    ledger.observe(gyro(0))
    ledger.adjacent(since, 2 * P)
    if overrun:
        ledger.overrun(2 * P)
    if note:
        ledger.note(note)
    ledger.observe(gyro(2 * P))
    assert (sum(ledger.lost.values()), ledger.not_measured) == (1, 0)


@pytest.mark.parametrize("since, until", [
    (0, P + P // 3),  # nothing for less than 1.5 periods: a slow chip clock, not a hang
    (-P, 4 * P),  # reads that began before the latest frame prove nothing about after it
])
def test_reads_that_prove_no_hang_leave_the_slots_lost(since: int, until: int) -> None:
    ledger = FrameLedger(Quantity.GYRO, P)
    ledger.observe(gyro(0))
    ledger.idle(since, until)
    ledger.observe(gyro(5 * P))
    assert (dict(+ledger.lost), ledger.not_measured) == ({"missed": 4}, 0)


def test_a_reset_in_the_gap_keeps_its_slots_counted_to_the_reset() -> None:
    ledger = FrameLedger(Quantity.GYRO, P)
    ledger.observe(gyro(0))
    ledger.idle(0, 3 * P)
    ledger.note("reset")
    ledger.observe(gyro(6 * P))
    assert (dict(+ledger.lost), ledger.not_measured) == ({"reset": 5}, 0)


def test_the_proof_of_a_hang_ends_at_the_next_frame() -> None:
    ledger = FrameLedger(Quantity.GYRO, P)
    ledger.observe(gyro(0))
    ledger.idle(0, 3 * P)
    ledger.observe(gyro(4 * P))
    ledger.note("bus_error")
    ledger.observe(gyro(8 * P))
    assert (dict(+ledger.lost), ledger.not_measured) == ({"bus_error": 3}, 3)


def test_the_summary_line_names_the_slots_a_hung_chip_did_not_measure() -> None:
    counts = {"produced": 10, "delivered": 9, "lost_host_stall": 1, "not_measured": 12}
    assert describe_frames(counts) == ("produced 10, delivered 9, lost 1 (host stall 1); "
                                       "slots not measured (chip hung) 12")


def _counted(ledger: FrameLedger) -> tuple[dict[str, int], int | None, int | None]:
    return ledger.counts(), ledger.first_ns, ledger.last_ns


@pytest.mark.parametrize("times, flags", [
    ([P, 2 * P, 3 * P + 100_000, 4 * P], [0, 0, 0, 0]),  # regular: counted on arrays
    ([6 * P, 7 * P, 11 * P, 12 * P], [0, 0, 0, 0]),  # a gap inside the block
    ([P, 2 * P, 3 * P, 4 * P], [0, int(SampleFlag.FROZEN), 0, int(SampleFlag.STALE)]),
], ids=["regular", "gap inside", "flagged frames"])
def test_a_block_is_counted_as_its_frames_one_by_one(times: list[int],
                                                     flags: list[int]) -> None:
    block = Block.from_samples([gyro(t, SampleFlag(f)) for t, f in zip(times, flags,
                                                                        strict=True)])
    by_block, by_frame = FrameLedger(Quantity.GYRO, P), FrameLedger(Quantity.GYRO, P)
    for ledger in (by_block, by_frame):
        ledger.observe(gyro(0))
        ledger.note("bus_error")
    losses = by_block.observe_block(block)
    frame_losses = [(s.t_ns, loss) for s in block.samples()
                    if (loss := by_frame.observe(s)) is not None]
    assert losses == frame_losses
    assert _counted(by_block) == _counted(by_frame)
    assert by_block.all_segments() == by_frame.all_segments()


FAST = P * 50 // 51  # a chip 2 % fast: 51 frames in 50 nominal periods


def _gap_after_a_run(chip_timed: bool, gap_periods: int) -> FrameLedger:
    """40 frames of a chip 2 % fast, then ``gap_periods`` of its periods without a frame
    (a stall past its FIFO's depth, counted as an overflow), then one frame."""
    ledger = FrameLedger(Quantity.GYRO, P, chip_timed=chip_timed)
    for k in range(40):
        ledger.observe(gyro(k * FAST))
    ledger.note("fifo_overflow")
    ledger.observe(gyro((39 + gap_periods) * FAST))
    return ledger


def test_a_chip_timed_gap_is_counted_in_the_period_its_stamps_show() -> None:
    # 39 chip periods are 38.2 nominal ones: 37 frames lost on the nominal period, 38 made
    assert dict(_gap_after_a_run(True, 39).lost) == {"fifo_overflow": 38}


def test_a_poll_stamped_gap_is_counted_in_the_nominal_period() -> None:
    assert dict(_gap_after_a_run(False, 39).lost) == {"fifo_overflow": 37}


def test_a_chip_timed_gap_after_a_short_run_keeps_the_nominal_period() -> None:
    ledger = FrameLedger(Quantity.GYRO, P, chip_timed=True)
    for k in range(5):  # too few frames to read a period off
        ledger.observe(gyro(k * FAST))
    ledger.note("fifo_overflow")
    ledger.observe(gyro((4 + 39) * FAST))
    assert dict(ledger.lost) == {"fifo_overflow": 37}


def test_a_chip_timed_period_read_from_a_block_counts_the_next_gap() -> None:
    ledger = FrameLedger(Quantity.GYRO, P, chip_timed=True)
    ledger.observe_block(Block.from_samples([gyro(k * FAST) for k in range(40)]))
    ledger.note("fifo_overflow")
    ledger.observe(gyro((39 + 39) * FAST))
    assert dict(ledger.lost) == {"fifo_overflow": 38}


def test_stamps_far_off_the_nominal_period_are_not_taken_for_the_chips() -> None:
    ledger = FrameLedger(Quantity.GYRO, P, chip_timed=True)
    slow = P * 13 // 10  # 30 % slow: no oscillator, a stamp error
    for k in range(40):
        ledger.observe(gyro(k * slow))
    ledger.note("fifo_overflow")
    ledger.observe(gyro(39 * slow + 20 * P))
    assert dict(ledger.lost) == {"fifo_overflow": 19}
