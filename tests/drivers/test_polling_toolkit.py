"""The shared polling toolkit: one poll grid, one stale policy, one reset watch."""

from __future__ import annotations

import pytest

from imuhal.drivers.polling import (
    MAX_STALE_POLLS_BEFORE_RESTART,
    STALE_AFTER_PERIODS,
    STALE_POLLS_BEFORE_RESTART,
    DataReady,
    PollGrid,
    ResetWatch,
)

PERIOD = 4_000_000


def test_grid_points_follow_the_anchor_one_period_apart() -> None:
    grid = PollGrid(PERIOD)
    grid.anchor(1_000)
    assert [grid.next_after(1_000), grid.next_after(1_000)] == [1_000 + PERIOD,
                                                               1_000 + 2 * PERIOD]


def test_a_late_poll_skips_to_the_next_grid_point_instead_of_bunching() -> None:
    grid = PollGrid(PERIOD)
    grid.anchor(0)
    assert grid.next_after(int(3.5 * PERIOD)) == 4 * PERIOD


def test_the_grid_point_at_or_before_a_time_hands_nothing_out() -> None:
    grid = PollGrid(PERIOD)
    grid.anchor(1_000)
    assert [grid.point_at_or_before(1_000 + int(2.5 * PERIOD)),
            grid.point_at_or_before(1_000 + 2 * PERIOD)] == [1_000 + 2 * PERIOD] * 2
    assert grid.next_after(1_000) == 1_000 + PERIOD  # the first point, as if never asked


def test_an_early_grid_steps_short_of_the_period() -> None:
    grid = PollGrid(PERIOD, early_fraction=64)
    grid.anchor(0)
    assert grid.next_after(0) == PERIOD - PERIOD // 64


def _poll_a_chip(grid: PollGrid, chip_period_ns: float, seconds: float) -> tuple[int, int, int]:
    """Poll a chip that measures every ``chip_period_ns`` the way the MAX2110x driver does
    (a poll that finds nothing retries a guard later and locates the data there; an overrun
    re-anchors half a period earlier). Returns (polls, measurements read, overruns)."""
    end = round(seconds * 1e9)
    grid.anchor(grid.guard_ns)
    t, read, polls, overruns, searching = grid.next_after(0), 0, 0, 0, False
    while t < end:
        polls += 1
        measured = int(t // chip_period_ns)  # measurements completed by t
        if measured == read:
            searching = True
            t += grid.guard_ns
            continue
        if measured > read + 1:
            overruns += 1
            grid.anchor(t - grid.period_ns // 2)
        elif searching:
            grid.locate(t)
        searching = False
        read = measured
        t = grid.next_after(t)
    return polls, read, overruns


@pytest.mark.parametrize("clock_error", [-0.015, 0.0, 0.015])
def test_a_tracking_grid_follows_the_chips_own_period_with_few_empty_polls(
    clock_error: float,
) -> None:
    chip = PERIOD / (1 + clock_error)
    polls, read, overruns = _poll_a_chip(PollGrid(PERIOD, early_fraction=64, track=True),
                                         chip, 20.0)
    assert overruns == 0  # no measurement lost
    assert polls / read < 1.03  # an empty poll every few dozen periods, not every eight


def test_a_grid_that_does_not_track_finds_nothing_about_one_poll_in_eight() -> None:
    polls, read, overruns = _poll_a_chip(PollGrid(PERIOD, early_fraction=64), PERIOD, 20.0)
    assert overruns == 0
    assert polls / read > 1.08


def test_a_tracking_grid_steps_a_margin_short_of_the_learnt_period_and_anchor_forgets_it() -> None:
    grid = PollGrid(PERIOD, early_fraction=64, track=True)
    chip = PERIOD * 1.01  # a slow chip clock
    _poll_a_chip(grid, chip, 20.0)
    assert chip - chip / 256 < grid.step_ns < chip
    grid.anchor(0)
    assert grid.step_ns == PERIOD - PERIOD // 64


def test_a_tracking_grid_polled_late_goes_on_from_the_chips_phase_not_its_short_steps(
) -> None:
    """60 late polls (each 3 ms after its point) learn nothing of the phase: the point
    after them is one early step short of the chip's phase as located, not 61 (a period
    less 61 / 64 of one, 3.8 ms before it)."""
    grid = PollGrid(PERIOD, early_fraction=64, track=True)
    grid.anchor(0)
    t = grid.next_after(0)
    for _ in range(60):
        t = grid.next_after(t + 3_000_000)
    assert t % PERIOD == PERIOD - PERIOD // 64


def test_a_count_giving_a_period_far_off_the_nominal_one_is_not_learnt() -> None:
    """A located instant half a step later than the point before it (polls late by
    less than the half step the count tolerates) counts one period where 1.45 passed:
    learnt, the grid would step 1.3 periods and skip a frame unseen every few points
    (the gy91 MPU-9250 learnt 5.94 ms for its 5 ms after a chain of host stalls). No
    oscillator is PERIOD_ERROR_AT_MOST off: the count starts afresh and the grid keeps
    its early step."""
    grid = PollGrid(PERIOD, early_fraction=64, track=True)
    grid.anchor(0)
    grid.locate(grid.guard_ns)
    point = grid.next_after(grid.guard_ns)
    grid.locate(point + grid.guard_ns + int(0.45 * grid.step_ns))
    assert grid.step_ns == PERIOD - PERIOD // 64


def test_a_channel_is_stale_only_after_the_policy_number_of_periods() -> None:
    ready = DataReady({"gyro": PERIOD})
    ready.start(0)
    limit = round(STALE_AFTER_PERIODS * PERIOD)
    assert not ready.overdue("gyro", limit)
    assert ready.overdue("gyro", limit + 1)
    ready.fresh("gyro", limit)
    assert not ready.overdue("gyro", limit + 1)


def test_reset_watch_checks_every_interval_and_at_once_when_data_are_overdue() -> None:
    watch = ResetWatch(0.5)
    watch.start(0)
    assert not watch.check_due(100_000_000)
    assert watch.check_due(100_000_000, overdue=True)
    assert not watch.check_due(500_000_000)  # the overdue check rescheduled it
    assert watch.check_due(600_000_000)


def test_reset_watch_without_an_interval_never_schedules_a_check() -> None:
    watch = ResetWatch(None)
    watch.start(0)
    assert not watch.check_due(10**12, overdue=True)


def test_reset_watch_asks_for_a_restart_after_consecutive_stale_polls_only() -> None:
    watch = ResetWatch(1.0)
    watch.start(0)
    for _ in range(STALE_POLLS_BEFORE_RESTART - 1):
        assert not watch.stale_poll()
    watch.fresh_poll()
    results = [watch.stale_poll() for _ in range(STALE_POLLS_BEFORE_RESTART)]
    assert results == [False] * (STALE_POLLS_BEFORE_RESTART - 1) + [True]


def test_a_grid_needs_a_positive_period() -> None:
    with pytest.raises(ValueError, match="positive"):
        PollGrid(0)


def test_a_restart_that_did_not_help_waits_twice_as_long_before_the_next() -> None:
    watch = ResetWatch(1.0)
    watch.start(0)

    def polls_until_restart() -> int:
        n = 1
        while not watch.stale_poll():
            n += 1
        return n

    first, second, third = (polls_until_restart() for _ in range(3))
    assert (first, second, third) == (STALE_POLLS_BEFORE_RESTART, 2 * STALE_POLLS_BEFORE_RESTART,
                                       4 * STALE_POLLS_BEFORE_RESTART)
    watch.fresh_poll()
    assert polls_until_restart() == STALE_POLLS_BEFORE_RESTART


def test_restarts_of_a_dead_chip_are_spaced_at_most_the_cap_apart() -> None:
    watch = ResetWatch(1.0)
    watch.start(0)
    gaps = []
    for _ in range(12):
        n = 1
        while not watch.stale_poll():
            n += 1
        gaps.append(n)
    assert max(gaps) == MAX_STALE_POLLS_BEFORE_RESTART


@pytest.mark.parametrize("catch_up", [False, True])
def test_a_catch_up_grid_keeps_up_with_a_chip_faster_than_its_early_step(catch_up: bool
                                                                         ) -> None:
    """A chip 2 % fast outruns the 1/64 early step: a grid that never finds an empty poll
    never learns the chip's period and falls behind it (an overrun every ~240 periods); a
    ``catch_up`` grid doubles its shortfall once a nominal clock would have shown one."""
    grid = PollGrid(PERIOD, early_fraction=64, track=True, catch_up=catch_up)
    _, _, overruns = _poll_a_chip(grid, PERIOD / 1.02, 5.0)
    assert (overruns == 0) is catch_up


@pytest.mark.parametrize("clock_error", [-0.02, 0.0])
def test_a_catch_up_grid_polls_a_nominal_or_slow_chip_as_before(clock_error: float) -> None:
    chip = PERIOD / (1 + clock_error)
    assert _poll_a_chip(PollGrid(PERIOD, early_fraction=64, track=True, catch_up=True),
                        chip, 5.0) == \
        _poll_a_chip(PollGrid(PERIOD, early_fraction=64, track=True), chip, 5.0)
