"""The polling toolkit every driver shares: a poll grid, data-ready tracking with one stale
policy, and a reset watch that restarts a chip that lost its configuration or stopped
producing data.

A driver keeps the chip-specific parts (which register says "new data", which registers to
read back) and hands the timing decisions to these helpers, so every driver flags a missing
sample after the same number of periods and restarts a stuck chip after the same number of
stale polls. Times are ``int`` nanoseconds on the driver's clock.
"""

from __future__ import annotations

from collections.abc import Hashable, Mapping
from typing import Any

from pydantic import Field

STALE_AFTER_PERIODS = 2.5
"""A channel with no new data for longer than this many of its output periods is stale.

Two and a half periods tolerate one output lost to a chip clock a few percent slow, or to a
late poll that read a sample the period before, and flag the second one in a row."""

STALE_POLLS_BEFORE_RESTART = 4
"""Consecutive stale (or frozen) polls after which a driver restarts the chip itself: the
chip answers and kept its configuration but produces no new data (a hung measurement
engine), which a soft reset and reconfiguration cures."""
MAX_STALE_POLLS_BEFORE_RESTART = 256
"""A chip that a restart did not cure is restarted after twice as many stale polls each
time, up to this many, so a dead sensor is not reset continuously."""

RESET_CHECK_S_DEFAULT = 0.5
"""Default of the ``reset_check_s`` setting: how often a driver reads back its
configuration to catch a silent reset (brown-out, ESD)."""


def reset_check_field(default: float = RESET_CHECK_S_DEFAULT) -> Any:
    """The ``reset_check_s`` settings field, declared the same way in every driver."""
    return Field(
        default=default, gt=0, le=60,
        description="How often (s) the driver reads back its configuration to catch a "
                    "silent chip reset.",
    )


class PollGrid:
    """Poll instants on a grid ``anchor + k * step``; a late poll skips ahead to the next
    grid point instead of bunching polls.

    ``early_fraction`` (n > 0) shortens the step by ``period / n``: the grid then creeps
    earlier than a chip whose clock runs up to about ``1/n`` fast, and the driver re-anchors
    where data appears (see ``anchor`` and ``locate``).

    ``catch_up`` (with ``track``): a grid that has not learnt the chip's period and found
    no poll with nothing new for longer than a nominal clock allows doubles its shortfall
    (``_catch_up``): the MPU-9250's and AK8963's polled reads, whose chips show no
    overwritten frame, and the MAX2110x's, whose overrun bits re-anchor the grid at each
    frame lost behind a chip 2 % fast, with the same early step again.

    ``track`` (with ``early_fraction``): the grid learns the chip's own period from the
    instants ``locate`` reports and steps ``TRACK_MARGIN`` (or the estimate's uncertainty,
    when larger) short of it instead of ``period / early_fraction``, so an exact chip clock
    costs a poll that finds nothing every few dozen periods rather than every eight, and a
    chip clock a few percent off is followed as well as before.
    """

    TRACK_MARGIN = 512
    """Once the chip's period is known to better than this fraction of it, the tracking
    grid steps ``period / TRACK_MARGIN`` short of it (about 0.2 %: a clock that drifts less
    than this between two re-anchors is still approached from the early side)."""

    PERIOD_ERROR_AT_MOST = 0.1
    """The farthest a tracked chip's period can lie from its nominal one (the emulated chips'
    oscillators allow +-10 %, issue 25 +-2 %): a count that gives more missed periods, and
    is started afresh (the gy91 MPU-9250 learnt 5.94 ms for its 5 ms after a chain of host
    stalls and skipped a frame unseen every few periods)."""

    CATCH_UP_SLACK = 2
    """Grid points beyond the most a chip on its nominal clock can take to show the early
    step's poll that finds nothing (``locate``): a ``catch_up`` grid that has not learnt the
    chip's period and found no such poll in that many points is behind a chip faster than
    its early step (a clock 2 % fast against the 1/64 step), so it doubles its shortfall
    (``next_after``). A fault-free nominal clock never gets there: its polls are unchanged
    (faults that hide the empty polls can: bus errors, blank reads)."""

    def __init__(self, period_ns: int, *, early_fraction: int = 0, track: bool = False,
                 catch_up: bool = False, bounded: bool = True) -> None:
        if period_ns <= 0:
            raise ValueError(f"poll period must be positive, got {period_ns} ns")
        self.period_ns = period_ns
        self._early_fraction = early_fraction
        self._track = track and early_fraction > 0
        self._catch_up_on = catch_up and self._track
        self._bounded = bounded
        """A count giving a period more than PERIOD_ERROR_AT_MOST off is not learnt (False:
        poll plans before imuhal.core.poll_plan.CHIP_CLOCK_PLAN, whose recordings replay)."""
        self.step_ns = self._initial_step()
        self._anchor_ns = 0
        self._k = 0
        self._first_ns: int | None = None
        """The first located instant of the current count (tracking's baseline)."""
        self._last_ns: int | None = None
        self._periods = 0
        """Chip periods counted from ``_first_ns`` to ``_last_ns``."""
        self._chip_period_ns = float(period_ns)
        self._folded = 0
        """Chip periods moved into the anchor since the last located instant (late polls)."""
        self._folded_ns = 0
        self._unlocated = 0
        """Grid points handed out since the latest ``locate`` or ``anchor``."""
        self._located = False
        """A ``locate`` since the latest ``anchor`` (the chip's phase is known)."""
        self._learnt = False
        """A period learnt since the latest ``anchor`` (``locate`` counted periods)."""

    def _initial_step(self) -> int:
        fraction = self._early_fraction
        return self.period_ns - (self.period_ns // fraction if fraction else 0)

    @property
    def guard_ns(self) -> int:
        """An eighth of a period: how far after a measurement instant a poll aims, and how
        much later a poll that found nothing new retries."""
        return max(1, self.period_ns // 8)

    def anchor(self, t_ns: int) -> None:
        """Restart the grid with a point at ``t_ns``; a tracking grid forgets what it
        learnt of the chip's period (an overrun or a restart: the phase was lost)."""
        self._anchor_ns = t_ns
        self._k = 0
        self._folded = self._folded_ns = 0
        self._unlocated = 0
        self._located = self._learnt = False
        if self._track:
            self._first_ns = self._last_ns = None
            self._periods = 0
            self._chip_period_ns = float(self.period_ns)
            self.step_ns = self._initial_step()

    def locate(self, t_ns: int) -> None:
        """New data appeared within a guard before ``t_ns`` (a poll a guard earlier found
        none): restart the grid there and, when tracking, refine the chip's period.

        Between two such instants every grid point found one new measurement (a poll that
        found none would have located the data; two would have overrun), so the chip
        measured once per grid point handed out: the periods are counted, not guessed from
        a nominal period that may be a few percent off. Each instant lies within a guard
        after its measurement, so the period over the whole count since the first instant is
        good to ``guard / periods``. A count the elapsed time does not confirm (polls late by
        half a step or more) starts the count afresh."""
        points, folded, folded_ns = self._k, self._folded, self._folded_ns
        self._anchor_ns = t_ns
        self._k = 0
        self._folded = self._folded_ns = 0
        self._unlocated = 0
        self._located = True
        if not self._track:
            return
        steps = points + folded
        first, last = self._first_ns, self._last_ns
        # The located instant is the k-th grid point's retry, a guard after it, unless
        # polls ran late (the chip periods a late poll folded into the anchor included).
        if first is None or last is None or steps < 1 or abs(
                t_ns - last - folded_ns - points * self.step_ns - self.guard_ns) \
                > self.step_ns // 2:
            self._first_ns = self._last_ns = t_ns
            self._periods = 0
            return
        periods = self._periods + steps
        if self._bounded and abs((t_ns - first) / periods - self.period_ns) \
                > self.PERIOD_ERROR_AT_MOST * self.period_ns:
            # a count that missed periods (a chain of host stalls folded more than it
            # counted): no oscillator is that far off, so the count starts afresh
            self._first_ns = self._last_ns = t_ns
            self._periods = 0
            return
        self._last_ns = t_ns
        self._periods = periods
        self._learnt = True
        self._chip_period_ns = (t_ns - first) / self._periods
        margin = max(self.period_ns / self.TRACK_MARGIN, 2 * self.guard_ns / self._periods)
        self.step_ns = max(1, int(self._chip_period_ns - margin))

    def point_at_or_before(self, t_ns: int) -> int:
        """The latest point of the grid as anchored (``anchor + k * step``) at or before
        ``t_ns``, without handing it out (``next_after``'s state is left as it was)."""
        return self._anchor_ns + (t_ns - self._anchor_ns) // self.step_ns * self.step_ns

    def next_after(self, now_ns: int) -> int:
        """The next grid point strictly after ``now_ns`` and after the previous one handed out.

        A tracking grid polled more than a guard after its latest point (a late poll: a
        stalled host, a poll put off) learnt nothing of the chip's phase meanwhile, so it
        goes on from the chip's phase as estimated (the anchor plus whole periods of the
        learnt period) rather than from the steps it missed, each short of the period: over
        a long run of late polls that shortfall would move the grid before the chip's
        instants unseen (60 late polls at the 1/64 early step: 4.7 ms of a 5 ms period), and
        the polls after would read a frame up to a period old."""
        if self._track and self._k and \
                now_ns - self._anchor_ns - self._k * self.step_ns > self.guard_ns:
            periods = int((now_ns - self._anchor_ns) // self._chip_period_ns)
            shift = round(periods * self._chip_period_ns)
            self._anchor_ns += shift
            self._folded += periods
            self._folded_ns += shift
            self._k = 0
        if self._catch_up_on and not self._learnt:
            self._catch_up(now_ns)
        k = max(self._k + 1, (now_ns - self._anchor_ns) // self.step_ns + 1)
        self._k = k
        return self._anchor_ns + k * self.step_ns

    def _catch_up(self, now_ns: int) -> None:
        """One more grid point without a poll that found nothing, while the chip's period is
        not learnt: once more points than the early step needs on a nominal clock (a whole
        period of creep before the first ``locate`` since the anchor, a guard's after it,
        plus CATCH_UP_SLACK), the chip is faster than the step, and every poll from then on
        would fall further behind it (a frame overwritten unread every 1 / (error - 1/64)
        periods, which no stamp shows): the step's shortfall doubles, up to a guard. Only
        polls on time count: a late one (a stalled host) proves nothing of the grid's
        phase (counted through host stalls, it fired on nominal clocks in the fault
        matrix's ``host_stall`` and moved the seed GPS board's IMU timing)."""
        if now_ns - (self._anchor_ns + self._k * self.step_ns) > self.guard_ns:
            self._unlocated = 0
            return
        self._unlocated += 1
        shortfall = max(1, self.period_ns - self.step_ns)
        span = self.guard_ns if self._located else self.period_ns
        if self._unlocated > -(-span // shortfall) + self.CATCH_UP_SLACK:
            self.step_ns = self.period_ns - min(self.guard_ns, 2 * shortfall)
            self._unlocated = 0


class DataReady:
    """When each channel last had new data, and whether it is now stale (one policy:
    ``STALE_AFTER_PERIODS``)."""

    def __init__(self, periods_ns: Mapping[Any, int]) -> None:
        self.periods_ns = dict(periods_ns)
        self._last_ns: dict[Hashable, int] = dict.fromkeys(self.periods_ns, 0)

    def start(self, now_ns: int) -> None:
        """Every channel counts as fresh at ``now_ns`` (the chip was just configured)."""
        for key in self._last_ns:
            self._last_ns[key] = now_ns

    def fresh(self, key: Hashable, now_ns: int) -> None:
        """``key`` delivered new data at ``now_ns``."""
        self._last_ns[key] = now_ns

    def overdue(self, key: Hashable, now_ns: int) -> bool:
        """True when ``key`` has had no new data for more than STALE_AFTER_PERIODS periods."""
        return bool(now_ns - self._last_ns[key] > STALE_AFTER_PERIODS * self.periods_ns[key])


class ResetWatch:
    """Schedules the configuration read-back (every ``check_s``, and at once when data are
    overdue) and counts stale polls towards restarting a stuck chip."""

    def __init__(self, check_s: float | None) -> None:
        """``check_s``: read-back interval; None for a chip whose every poll already reads
        its configuration (the watch then only counts stale polls)."""
        self.check_ns = round(check_s * 1e9) if check_s is not None else None
        self._check_ns = self.check_ns
        self._next_check_ns = 0
        self._stale_polls = 0
        self._restart_after = STALE_POLLS_BEFORE_RESTART

    def spread_over(self, steps: int) -> None:
        """Check one of ``steps`` parts of the configuration at a time (a register plan's
        check steps, imuhal.bus.register_plan), each ``check_s / steps`` after the last,
        so the whole configuration is still read back every ``check_s``."""
        if self._check_ns is not None:
            self.check_ns = max(1, self._check_ns // max(1, steps))

    def start(self, now_ns: int) -> None:
        self._next_check_ns = now_ns + (self.check_ns or 0)
        self._stale_polls = 0

    def check_due(self, now_ns: int, *, overdue: bool = False) -> bool:
        """True when the driver should read its configuration back now; schedules the next
        check. ``overdue``: data are late, so check at once."""
        if self.check_ns is None or (not overdue and now_ns < self._next_check_ns):
            return False
        self._next_check_ns = now_ns + self.check_ns
        return True

    def stale_poll(self) -> bool:
        """Count a poll that found no new measurement; True once the chip should be
        restarted (after STALE_POLLS_BEFORE_RESTART in a row, twice as many after each
        restart that did not help, at most MAX_STALE_POLLS_BEFORE_RESTART)."""
        self._stale_polls += 1
        if self._stale_polls < self._restart_after:
            return False
        self._stale_polls = 0
        self._restart_after = min(2 * self._restart_after, MAX_STALE_POLLS_BEFORE_RESTART)
        return True

    def fresh_poll(self) -> None:
        """A poll found a new measurement: the chip works, restart early again next time."""
        self._stale_polls = 0
        self._restart_after = STALE_POLLS_BEFORE_RESTART
