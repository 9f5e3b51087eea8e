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


def test_an_early_grid_steps_short_of_the_period() -> None:
    grid = PollGrid(PERIOD, early_fraction=64)
    grid.anchor(0)
    assert grid.next_after(0) == PERIOD - PERIOD // 64


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
