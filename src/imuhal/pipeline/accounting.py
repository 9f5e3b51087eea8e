"""Every frame accounted for: per device, frames produced, delivered and lost by cause
(issue 25 item 5).

A driver that knows its chip's output period names the stream it accounts for
(``Driver.accounted_stream``: a channel and the chip's frame period). The pipeline hands its
ledger every sample of that channel and every event that can cost a frame; the ledger counts
the frames the chip produced from its timing: two valid frames delivered ``gap`` apart span
``round(gap / period)`` frame periods, so ``round(gap / period) - 1`` frames between them were
produced and not delivered. Those are lost, and charged to the weightiest cause seen since
the previous valid frame:

``reset``      the driver reprogrammed its chip (a recovery after bus errors, a detected
               silent reset, a restart of a stuck or frozen chip);
``host_stall`` a poll of the device came more than half a frame period after it was due
               (the host's one thread was busy: a stalled process, another device's slow
               poll or long recovery);
``bus_error``  a transfer failed (the driver resumed without a reset);
``stale``      the driver flagged a sample STALE (no new data for too long);
``flagged``    a produced frame came out flagged (FROZEN, BLANK, out of range...);
``missed``     none of these: the poll grid missed a frame (a chip clock faster than its
               nominal period, a poll that came just too late, a frame the chip's overrun
               bit says was overwritten unread), counted, never hidden.

Each loss counted before a delivered frame (:meth:`FrameLedger.observe` returns it) reaches
the estimators as a gap before that frame (imuhal.core.gaps.StreamGap).

A reconfiguration restarts the chip's stream with a new phase, so it ends a *segment*: the
slots of the configured period between the last valid frame before it and the first one after
are counted lost (``reset``) although the chip, being reset, produced no frames of the stream
in part of that time. Within a segment the count is the chip's: in emulation the chip's own
record of its measurement instants over each segment's span equals the segment's count
(tests/integration/test_frame_accounting.py), so a wrong period, a grid that repeats or skips
frames unseen, or a cause that goes uncounted fails there. ``delivered + sum(lost) ==
produced`` holds by construction. ``fifo_overflow``: a FIFO reader (the MPU-9250's ``read:
fifo``) found its chip's FIFO overflowed or corrupt and reset it (``DeviceHealth.
fifo_overflows``); it comes first, since a FIFO rides out the other causes. ``reset``
comes before ``host_stall``: a gap across the device's own reconfiguration ends its segment
and its stream restarts, so its frames are the reset's even when the thread was also held
in that window (another device's recovery); a device that was only kept waiting loses its
frames to ``host_stall``.

A poll that comes half a period late or more is put off to the next point of the device's
own poll grid (imuhal.pipeline.pipeline, ``Pipeline._on_phase``; up to PUT_OFF_AT_MOST times
in a row): its reading keeps the phase of the polls before it, so the gap that ends in it is
counted like any other, exactly. A poll late by less than half a period reads the frame it
was due for and is counted at its due time, one made off its grid after the put-offs at the
grid point before it (:meth:`FrameLedger.count_at`; such a poll that fails on a bus error
and is retried at once is counted there too, :meth:`FrameLedger.retried`). The late
poll's ``host_stall`` is noted with its due time (``note(at_ns=)``) and charged to the gap
that spans it: an auto-read slave's first poll after a stall hands out its master's copy
from before the stall first.

A chip whose conversions the host starts (the MS5611) produces no frame in a slot of its
configured cadence that the host let pass without a conversion (its schedule slid after a
late poll: a stalled host, another device's long recovery, a failed convert command): the
driver reports the time its schedule slid (``DeviceHealth.not_converted_ns``), the ledger
takes it out of the gap before counting its frames, and counts the slots apart as
``not_converted``: the chip never made those frames, so they are neither produced nor lost,
and ``delivered + lost = produced`` still equals the chip's own count. A gap of such slots
still reaches the estimators (cause ``not_converted``: the time between the frames is real).

A chip that hung (its engine stopped: the fault API's ``stuck_data_ready``) made no frame
in the slots it let pass, so they are neither produced nor lost either: the ledger counts
them apart as ``not_measured``. Only what the driver read from the chip says so
(``DeviceHealth.idle``, ``DeviceHealth.overrun_ns``; the AK8963 read directly reports
both, from its ST1 bits, the MAX2110x from its status register): an unbroken run of good
reads from the latest valid frame's read, each finding no new measurement (DRDY clear),
that reached HUNG_AFTER_PERIODS periods past
that frame proves the chip let an instant pass (half a period after it was due: no
oscillator error does that), so the chip hung (:meth:`FrameLedger.idle`). It is taken as
hung until a read finds it measuring again; of the slots between, it made only the one its
overrun bit proves (ST1.DOR: a measurement overwritten unread, lost; the bit cannot count
more than one), and the others are ``not_measured``. A chip that resumed while the host was
not looking (another device's recovery holding the thread) and then overwrote more than one
measurement is so counted as losing one of them: the limit of a one-bit overrun flag, stated
in docs/acquisition.md. Reads that found nothing for less than HUNG_AFTER_PERIODS prove
nothing the ledger uses (a chip clock 2 % slow, a poll a guard early). A reset in the gap
ends the segment: its slots stay ``reset``. Behind an auto-read master the master's copies
are those reads: the AK8963's ST1 rides in every copy the MPU-9250's slave 0 makes; the
HMC5883L behind the MAX21100, whose copies lack its status, reads its status register when
its bytes have stayed the same longer than a measuring chip allows. Without such reads (no
read during the hang) the slots count as lost, as before. A hang shorter than
HUNG_AFTER_PERIODS is proved by the read of the field after it instead
(``DeviceHealth.adjacent``, :meth:`FrameLedger.adjacent`): unbroken good reads since the
latest valid frame that found nothing new, then a new measurement with the overrun bit clear
(the AK8963's ST1.DOR, set by a measurement that overwrites one unread and cleared by every
read), so the chip measured once between the two frames and any slot their stamps span is
``not_measured``: behind slave 0 the quiet copies, dated a feed latency early, never reach
1.5 periods when the chip lets one measurement pass (the fault matrix's 9 ms window). Such
reads also span the slots between the two frames' *stamps*: where the frame before was
counted at a point off its stamp (``count_at``) and that point lies more periods before the
next frame than its stamp, the count moved frames out of the gap before it (a poll after
its put-offs, between the chip's instant and the next point of the phase it was counted
on), and they are counted lost there, to that gap's cause (:meth:`FrameLedger._displaced`).

Limit: time stamps are the host's poll times, up to a period after the measurement. A gap
is counted right while the two polls at its ends lie at about the same phase to the chip
(within half a period): the drivers that search their chip's instants (the MPU-9250, the
AK8963 read directly, the MAX2110x) poll within a guard after them; a chip clock off its
nominal period by more than half a period over a long gap (2 % over 25 periods) can still
shift the count by one, except where the chip's overrun bit shows the frame the grid
skipped (the MAX2110x's overrun bits: :meth:`FrameLedger.skipped`, at least one frame lost
before the frame whose read found it). Frame times from the chip
(FIFO reads, data-ready lines) remove this limit. A stream stamped at its chip's instants
(``FrameLedger.chip_timed``: a FIFO read, a data-ready line's edges) counts a gap in the
period its consecutive frames' stamps show, so a gap past 25 periods of a chip 2 % off (a
stall longer than the FIFO's depth) is exact too.
"""

from __future__ import annotations

from collections import Counter
from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np

from imuhal.core.blocks import Block
from imuhal.core.samples import Quantity, Sample, SampleFlag

CAUSES: tuple[str, ...] = ("fifo_overflow", "reset", "host_stall", "bus_error", "stale",
                           "flagged", "missed")
"""Loss causes, weightiest first: a gap is charged to the first one seen in it."""


NOT_MEASURED = "not_measured"
"""The cause of a gap in which a hung chip made no frame: slots its driver's reads proved
unmeasured (counted apart, not lost)."""

HUNG_AFTER_PERIODS = 1.5
"""Reads finding nothing new this many frame periods after the latest valid frame: the chip
let an instant pass by half a period, which no oscillator error (+-2 %) explains."""

RUN_FOR_PERIOD = 32
"""Consecutive frames (no slot between any two) a stream stamped on its chip's clock must
show before the ledger counts its gaps in the period their stamps give (``chip_timed``)."""

STAMP_PERIOD_AT_MOST = 0.1
"""A period read off the stamps more than this fraction off the nominal one is not the
chip's (a stamp error, not an oscillator: +-2 %): the nominal period stays."""

NOT_CONVERTED = "not_converted"
"""The cause of a gap in which a host-paced chip made no frame: slots of its configured
cadence it never converted (counted apart, not lost)."""


class Loss(NamedTuple):
    """Slots without a delivered frame just before a delivered frame (what becomes a
    StreamGap): frames lost, and for a host-paced chip also slots it never converted."""

    frames: int
    cause: str
    """The weightiest cause of the frames lost; NOT_CONVERTED when none was lost."""
    last_ns: int
    """The time stamp of the frame delivered before the loss."""


@dataclass
class FrameLedger:
    """The frame count of one device's accounted stream."""

    channel: Quantity
    period_ns: int
    delivered: int = 0
    lost: Counter[str] = field(default_factory=Counter)
    first_ns: int | None = None
    """Time stamp of the first valid frame (the counted span starts there)."""
    last_ns: int | None = None
    """Time stamp of the latest valid frame."""
    segments: list[tuple[int, int, int]] = field(default_factory=list)
    """Closed segments (first and last valid frame's time stamp, frames produced from the
    first to the last), one per stretch between reconfigurations."""
    not_converted: int = 0
    """Slots of the configured cadence in which the chip made no frame: its conversions are
    the host's to start and the host's schedule slid past them (neither produced nor
    lost)."""
    not_measured: int = 0
    """Slots of the configured period in which a hung chip made no frame, as its driver's
    reads proved (``idle``; neither produced nor lost)."""
    _idle_ns: int | None = None
    """The latest read, since the latest valid frame's, that found the chip had made nothing
    since that frame (``idle``)."""
    _overrun_ns: int | None = None
    """The stamp of a frame whose read found a measurement overwritten unread (``overrun``)."""
    _adjacent: tuple[int, int] | None = None
    """(earlier, later) stamps of two frames the chip made none between (``adjacent``)."""
    _seen: set[str] = field(default_factory=set)
    """Causes seen since the latest valid frame."""
    _pending: list[tuple[int, str]] = field(default_factory=list)
    """Causes noted with the time they began (``note(at_ns=)``) later than the latest valid
    frame: each waits for the first valid frame stamped after it, whose gap it spans."""
    _slid_ns: int = 0
    """Time the driver's conversion schedule slid since the latest valid frame."""
    _segment_first_ns: int | None = None
    _segment_produced: int = 0
    _last_counted_ns: int = 0
    """Where the latest valid frame is counted from: its stamp, or the due time of the late
    poll that read it (``count_at``)."""
    _skipped_ns: int | None = None
    """The stamp of a frame whose read found one of the stream overwritten (``skipped``)."""
    _off_phase: tuple[int, int] | None = None
    """(stamp, due time) of a late poll (``count_at``)."""
    _off_unless_skipped: bool = False
    """``_off_phase`` holds unless the frame's read found one overwritten (``count_at``)."""
    _retry_until_ns: int = 0
    """A late poll that failed is retried at once (``retried``): a valid frame stamped after
    ``_off_phase``'s stamp and up to this is the retry's, counted at its due time."""
    chip_timed: bool = False
    """The stream's stamps are its chip's measurement instants (a FIFO read on the chip's
    clock, imuhal.drivers.chip_clock; a data-ready line's edges): a gap is counted in the
    period consecutive frames' stamps show, not the nominal one. A chip 2 % fast makes 39
    frames in 38 nominal periods, so a gap longer than 25 periods (a host stall past the
    FIFO's depth) would round to a frame less than the chip made."""
    _run: tuple[int, int] | None = None
    """(first stamp, frames) of the latest run of frames with no slot between them."""
    _stamp_period_ns: float | None = None
    """The chip's period as the latest run of RUN_FOR_PERIOD frames or more showed it
    (``chip_timed``; None: not seen yet)."""
    _off_cause: str = "missed"
    """The weightiest cause of the gap before the latest valid frame, when that frame was
    counted off its stamp (``count_at``): what frames its count moved out of that gap
    were lost to (``_displaced``)."""

    def __post_init__(self) -> None:
        if self.period_ns <= 0:
            raise ValueError(f"frame period must be positive, got {self.period_ns} ns")

    @property
    def produced(self) -> int:
        """Frames the chip produced from the first valid frame to the latest one."""
        return self.delivered + sum(self.lost.values())

    @property
    def counted_ns(self) -> int | None:
        """Where the latest valid frame is counted from (its stamp, or the grid point of the
        late poll that read it: ``count_at``); None before the first."""
        return None if self.last_ns is None else self._last_counted_ns

    def note(self, cause: str, *, at_ns: int | None = None) -> None:
        """Something that can cost frames happened (one of CAUSES); ``reset`` also ends the
        current segment. ``at_ns``: when it began (a late poll's due time), for a cause
        that a poll notes before it hands out frames stamped earlier than that (an
        auto-read slave's copies from before a stall, delivered by its master, come out
        after the stall with their own stamps): the cause belongs to the gap that spans
        ``at_ns``, not to a gap a frame from before it closes."""
        if cause not in CAUSES:
            raise ValueError(f"unknown loss cause {cause!r}; one of {', '.join(CAUSES)}")
        if at_ns is not None and self.last_ns is not None and at_ns > self.last_ns:
            self._pending.append((at_ns, cause))
            return
        self._seen.add(cause)
        if cause == "reset" and self._segment_first_ns is not None:
            assert self.last_ns is not None
            self.segments.append((self._segment_first_ns, self.last_ns, self._segment_produced))
            self._segment_first_ns = None

    def slid(self, ns: int) -> None:
        """The driver's schedule of a host-paced chip slid by ``ns`` without a conversion
        (``DeviceHealth.not_converted_ns``): that time holds no frame of the chip's."""
        if ns < 0:
            raise ValueError(f"a schedule slides forward, got {ns} ns")
        self._slid_ns += ns

    def idle(self, since_ns: int, until_ns: int) -> None:
        """Good reads from the one that read the frame stamped ``since_ns`` to the one at
        ``until_ns`` found no new measurement (a data-ready bit clear each time): the chip
        made no frame between. Counts only when ``since_ns`` is the latest valid frame."""
        if since_ns == self.last_ns and until_ns > since_ns:
            self._idle_ns = until_ns if self._idle_ns is None else max(self._idle_ns, until_ns)

    def overrun(self, stamp_ns: int) -> None:
        """The read that brought the frame stamped ``stamp_ns`` found that the chip had
        overwritten a measurement unread since the read before (the AK8963's ST1.DOR, the
        MAX2110x's overrun bit): of a hung chip's slots, the one lost (``idle``)."""
        self._overrun_ns = stamp_ns

    def adjacent(self, since_ns: int, stamp_ns: int) -> None:
        """The read that brought the frame stamped ``stamp_ns`` proved that the chip made
        no frame since the one stamped ``since_ns`` (``DeviceHealth.adjacent``: unbroken
        good reads that found nothing new, then this one's new measurement with the overrun
        bit clear): any slot the stamps span between them is one the chip let pass
        (``not_measured``), however short its hang. Counts only when ``since_ns`` is the
        latest valid frame when the frame stamped ``stamp_ns`` comes."""
        self._adjacent = (since_ns, stamp_ns)

    def skipped(self, stamp_ns: int) -> None:
        """The driver's own read that brought the frame stamped ``stamp_ns`` found a frame
        of the stream overwritten unread since its read before (the MAX2110x's overrun
        bit): at least one frame lies between it and the frame before, lost, whatever the
        stamps say. Also for a copy a bus master made whose slave's status says so (the
        AK8963's ST1.DOR behind slave 0): such a copy is placed on the chip's cadence at
        least two periods after the field before (``stamp_on_cadence(at_least=)``), but
        never after its delivery, and the field before may lag its own measurement by more
        (the first copy of a segment, stamped at its delivery after failed slave reads)."""
        self._skipped_ns = stamp_ns

    def count_at(self, stamp_ns: int, at_ns: int, *, unless_skipped: bool = False) -> None:
        """A poll made at ``stamp_ns`` was due at ``at_ns`` (a point of its device's grid): a
        frame it delivers stamped ``stamp_ns`` carries the measurement a poll at ``at_ns``
        would have read (the chip's next instant still ahead then, for a grid less than half
        a period after its chip's instants), so its gaps are counted from ``at_ns``: from
        its stamp a lateness of half a period or more between the two ends of a gap would
        round to one frame more or less. A poll late by less than half a period, and one
        made off its grid after PUT_OFF_AT_MOST put-offs (counted from the grid point
        before it) (``Pipeline._on_phase``). ``unless_skipped``: ``at_ns`` stands for the
        frame after the latest one only if the chip's next instant had not come by
        ``stamp_ns`` (a late retry, ``Pipeline._count_late_retry``); a read that found a
        frame overwritten unread (``skipped``) read a later one, and is counted at its
        stamp."""
        self._off_phase = (stamp_ns, at_ns)
        self._off_unless_skipped = unless_skipped
        self._retry_until_ns = 0

    def retried(self, failed_ns: int) -> None:
        """The poll made at ``failed_ns`` failed on a bus error and its driver retries it at
        once (``Driver.resume``): the retry reads the frame the failed poll was due for, so
        a ``count_at`` of the failed poll is the retry's, for a valid frame stamped within a
        guard (an eighth of a period) after it. The retry's stamp differs (by 1 ns at
        least), and counted from it a put-off poll 1.7 ms late of 4 ms, retried after a bus
        error, rounded a gap of 2.55 periods to a frame the chip never made (the seed
        paraglider's MAX21100 at 10 % bus errors, OS errors and all-ones reads, seeds 3
        and 7)."""
        if self._off_phase is not None and self._off_phase[0] == failed_ns:
            self._retry_until_ns = failed_ns + self.period_ns // 8

    def all_segments(self) -> list[tuple[int, int, int]]:
        """The closed segments and the open one."""
        if self._segment_first_ns is None or self.last_ns is None:
            return list(self.segments)
        return [*self.segments, (self._segment_first_ns, self.last_ns, self._segment_produced)]

    def observe(self, sample: Sample) -> Loss | None:
        """A sample of the device as the pipeline hands it out (flags final); returns the
        frames counted lost just before it (a valid frame of the accounted channel after a
        gap), else None."""
        if sample.channel is not self.channel:
            return None
        if not sample.valid:
            self.note("stale" if sample.flags & SampleFlag.STALE else "flagged")
            return None
        return self._valid_at(sample.t_ns)

    def _valid_at(self, t_ns: int) -> Loss | None:
        """A valid frame of the accounted channel at ``t_ns`` (``observe``)."""
        if self._pending:
            self._take_pending(t_ns)
        loss = None
        counted_ns = t_ns
        off = self._off_phase
        if off is not None and (off[0] == t_ns or off[0] < t_ns <= self._retry_until_ns):
            if not (self._off_unless_skipped and self._skipped_ns == t_ns):
                counted_ns = off[1]
            self._off_phase = None
        if self.last_ns is not None:
            adjacent = self._adjacent == (self.last_ns, t_ns)
            step_ns = counted_ns - self._last_counted_ns
            displaced = self._displaced(t_ns, step_ns) if adjacent else 0
            loss = self._gap_before(step_ns - displaced * self.period_ns,
                                    overrun=self._overrun_ns == t_ns,
                                    overwritten=self._skipped_ns == t_ns,
                                    adjacent=adjacent)
            if displaced:
                loss = self._displaced_lost(displaced, loss)
        else:
            self.first_ns = t_ns
        if counted_ns != t_ns:
            self._off_cause = next((c for c in CAUSES if c in self._seen), "missed")
        if self._segment_first_ns is None:
            self._segment_first_ns = t_ns
            self._segment_produced = 0
        if self.chip_timed:
            self._extend_run(t_ns, 1, after_gap=loss is not None or self.last_ns is None)
        self._segment_produced += 1
        self.delivered += 1
        self.last_ns = t_ns
        self._last_counted_ns = counted_ns
        self._seen.clear()
        self._slid_ns = 0
        self._idle_ns = None
        if self._overrun_ns is not None and self._overrun_ns <= t_ns:
            self._overrun_ns = None
        if self._skipped_ns is not None and self._skipped_ns <= t_ns:
            self._skipped_ns = None
        return loss

    def observe_block(self, block: Block) -> list[tuple[int, Loss]]:
        """``observe`` for every frame of ``block`` (one stream, flags final), oldest first;
        returns each loss with the time of the frame it comes before. A block of valid
        frames none of which follows the one before by half a period more than the period
        (so no slot lies between them) is counted on its arrays: only its first frame can
        come after a gap; any other block goes frame by frame."""
        if block.quantity is not self.channel:
            return []
        t = block.t_ns
        if len(t) > 1 and not block.flagged:
            steps = t[1:] - t[:-1]  # np.diff, min and max through their Python wrappers
            # cost more than the arithmetic on a read's few frames: the ufuncs directly
            if int(_MIN(steps)) >= 0 and 2 * int(_MAX(steps)) < 3 * self.period_ns:
                first = int(t[0])
                loss = self._valid_at(first)
                more = len(t) - 1
                if self.chip_timed:
                    self._extend_run(first, more, after_gap=False)
                self.delivered += more
                self._segment_produced += more
                self.last_ns = self._last_counted_ns = int(t[-1])
                if self._pending:  # spanned by the block's steps, none of which lost a frame
                    self._take_pending(self.last_ns)
                    self._seen.clear()
                return [] if loss is None else [(first, loss)]
        out = []
        for sample in block.samples():
            loss = self.observe(sample)
            if loss is not None:
                out.append((sample.t_ns, loss))
        return out

    def _extend_run(self, t_ns: int, frames: int, *, after_gap: bool) -> None:
        """``frames`` more frames of the current run (``chip_timed``); a gap before the
        frame at ``t_ns`` starts a new run there."""
        if after_gap or self._run is None:
            self._run = (t_ns, frames)
        else:
            self._run = (self._run[0], self._run[1] + frames)

    def _gap_period_ns(self) -> float:
        """The period a gap after the latest valid frame is counted in: the nominal one, or
        for a ``chip_timed`` stream the one the run before the gap showed (a run of
        RUN_FOR_PERIOD frames or more, within STAMP_PERIOD_AT_MOST of the nominal), else
        the one an earlier run showed (the oscillator is the same across a reset)."""
        if not self.chip_timed:
            return self.period_ns
        run = self._run
        if run is not None and run[1] >= RUN_FOR_PERIOD and self.last_ns is not None:
            shown = (self.last_ns - run[0]) / (run[1] - 1)
            if abs(shown - self.period_ns) <= STAMP_PERIOD_AT_MOST * self.period_ns:
                self._stamp_period_ns = shown
        return self._stamp_period_ns or self.period_ns

    def _displaced(self, t_ns: int, step_ns: int) -> int:
        """Frames a ``count_at`` of the latest valid frame moved out of the gap before it,
        as the reads that proved the frame at ``t_ns`` adjacent to it show (``adjacent``:
        the chip made nothing between the two reads, so their stamps span the slots
        between, not the points they were counted at). A late poll after its put-offs that
        came between the chip's instant and the next point of the phase it was counted on
        (a frame's lag after that instant) read the frame of that point and was counted at
        the point before: a period early (gy91's AK8963, fault matrix ``host_stall`` at
        10 %, seeds 4 and 6: 25 us before the point, 1.3 ms after the instant). Not across
        a reset: the frame before ended its segment."""
        if self._last_counted_ns == self.last_ns or "reset" in self._seen:
            return 0
        assert self.last_ns is not None
        by_stamp = max(1, round((t_ns - self.last_ns) / self.period_ns))
        return max(0, round(step_ns / self.period_ns) - by_stamp)

    def _displaced_lost(self, frames: int, loss: Loss | None) -> Loss:
        """Count ``frames`` displaced out of the gap before the latest valid frame
        (``_displaced``) as lost to that gap's cause: the chip made them before it."""
        assert self.last_ns is not None
        self.lost[self._off_cause] += frames
        if self._segment_first_ns is not None:
            self._segment_produced += frames
        if loss is None or loss.cause in (NOT_MEASURED, NOT_CONVERTED):
            return Loss(frames + (loss.frames if loss else 0), self._off_cause, self.last_ns)
        return Loss(frames + loss.frames, loss.cause, self.last_ns)

    def _take_pending(self, t_ns: int) -> None:
        """The timed causes that began by ``t_ns`` join the causes of the gap ending there."""
        due = [cause for at_ns, cause in self._pending if at_ns <= t_ns]
        if due:
            self._seen.update(due)
            self._pending = [(at, c) for at, c in self._pending if at > t_ns]

    def _gap_before(self, step_ns: int, *, overrun: bool = False,
                    overwritten: bool = False, adjacent: bool = False) -> Loss | None:
        """Counts the slots between the latest valid frame and one ``step_ns`` after it:
        frames lost (charged to the weightiest cause seen), slots never converted and slots
        a hung chip did not measure. ``overrun``: the frame's read found a measurement
        overwritten unread (a hung chip's one lost slot); ``overwritten``: the driver's own
        read found a frame of the stream overwritten (at least one lost, ``skipped``);
        ``adjacent``: its read proved the chip made none since the frame before
        (``adjacent``: every slot between is not measured)."""
        assert self.last_ns is not None
        period = self._gap_period_ns()
        slots = round(step_ns / period) - 1
        if slots <= 0 and not overwritten:  # the next slot (nearly every frame), nothing
            return None  # overwritten unread: nothing below can count
        lost = max(0, min(slots, round((step_ns - self._slid_ns) / period) - 1))
        if overwritten and slots < 1:
            # the chip overwrote a frame unread since the read before: one frame lies
            # between them whatever the stamps say (a poll grid that drifted past an instant
            # reads the frame after it one period after the one before)
            slots = lost = 1
        skipped = max(0, slots - lost)
        self.not_converted += skipped
        unmeasured = min(lost, self._unmeasured(lost, overrun, adjacent))
        self.not_measured += unmeasured
        lost -= unmeasured
        if lost:
            cause = next((c for c in CAUSES if c in self._seen), "missed")
            self.lost[cause] += lost
            if self._segment_first_ns is not None:
                self._segment_produced += lost
            return Loss(lost + skipped + unmeasured, cause, self.last_ns)
        if unmeasured:
            return Loss(unmeasured + skipped, NOT_MEASURED, self.last_ns)
        return Loss(skipped, NOT_CONVERTED, self.last_ns) if skipped else None

    def _unmeasured(self, slots: int, overrun: bool, adjacent: bool = False) -> int:
        """Of ``slots`` slots before a valid frame, those a hung chip did not measure: all
        but the one its overrun bit proves, once the reads since the latest valid frame
        proved it hung (``idle``; the module's docstring), all of them when the frame's
        read proved the chip made none since (``adjacent``), and none in a gap its driver
        reconfigured it in."""
        if "reset" in self._seen:
            return 0
        if adjacent and not overrun:
            return slots
        if self._idle_ns is None:
            return 0
        # from the latest frame's read (its stamp), not the due time a late poll is counted
        # at: the chip's next instant came within a period after that read
        assert self.last_ns is not None
        if (self._idle_ns - self.last_ns) < HUNG_AFTER_PERIODS * self.period_ns:
            return 0
        return max(0, slots - int(overrun))

    def counts(self) -> dict[str, int]:
        """produced, delivered and ``lost_<cause>`` for every cause (zeros included),
        ``not_converted`` for a host-paced chip that skipped slots and ``not_measured`` for a
        hung chip's slots (each absent when 0)."""
        return {"produced": self.produced, "delivered": self.delivered,
                **{f"lost_{c}": self.lost[c] for c in CAUSES},
                **({NOT_CONVERTED: self.not_converted} if self.not_converted else {}),
                **({NOT_MEASURED: self.not_measured} if self.not_measured else {})}


_MIN = np.minimum.reduce
_MAX = np.maximum.reduce


def describe_frames(counts: dict[str, int]) -> str:
    """One line of a run summary: ``produced 1000, delivered 990, lost 10 (bus error 6,
    reset 4)``."""
    lost = {k.removeprefix("lost_"): v for k, v in counts.items()
            if k.startswith("lost_") and v}
    text = f"produced {counts['produced']}, delivered {counts['delivered']}"
    if lost:
        text += f", lost {sum(lost.values())} (" + ", ".join(
            f"{k.replace('_', ' ')} {v}" for k, v in lost.items()) + ")"
    if counts.get(NOT_CONVERTED):
        text += f"; slots not converted {counts[NOT_CONVERTED]}"
    if counts.get(NOT_MEASURED):
        text += f"; slots not measured (chip hung) {counts[NOT_MEASURED]}"
    return text
