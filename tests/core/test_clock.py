"""Clocks: a simulated clock jumps, or paces itself against the wall clock when asked."""

from __future__ import annotations

import pytest

from imuhal.core import clock as clock_module
from imuhal.core.clock import MonotonicClock, SimulatedClock


def test_a_simulated_clock_moves_only_forward_when_told() -> None:
    c = SimulatedClock(100)
    c.sleep_until(50)
    assert c.now_ns() == 100
    c.sleep(0.5)
    assert c.now_ns() == 500_000_100


def test_an_unpaced_simulated_clock_never_sleeps(monkeypatch: pytest.MonkeyPatch) -> None:
    slept: list[float] = []
    monkeypatch.setattr(clock_module.time, "sleep", slept.append)
    SimulatedClock().sleep_until(10_000_000_000)
    assert slept == []


class FakeWall:
    """The wall clock a paced clock reads (``ns``, moved by the test) and the sleeps it
    asked for (s), in place of ``time.monotonic_ns`` and ``time.sleep``."""

    def __init__(self) -> None:
        self.ns = 1_000_000_000
        self.slept: list[float] = []


@pytest.fixture
def wall(monkeypatch: pytest.MonkeyPatch) -> FakeWall:
    fake = FakeWall()
    monkeypatch.setattr(clock_module.time, "monotonic_ns", lambda: fake.ns)
    monkeypatch.setattr(clock_module.time, "sleep", fake.slept.append)
    return fake


def test_a_paced_simulated_clock_waits_for_the_wall_clock(wall: FakeWall) -> None:
    c = SimulatedClock(realtime=True)
    wall.ns += 200_000_000  # 0.2 s of wall time passed
    c.sleep_until(500_000_000)  # simulated 0.5 s: 0.3 s still to wait
    assert wall.slept == [pytest.approx(0.3)]


def test_a_paced_simulated_clock_that_fell_behind_resumes_at_the_walls_pace(
        wall: FakeWall) -> None:
    """Set-up before a run's loop took wall time with the simulated clock standing: the run
    must not race through that lag (a stopped run said "ran 4.2 s in 3.39 s wall time")."""
    c = SimulatedClock(realtime=True)
    wall.ns += 1_000_000_000  # 1 s of set-up
    c.sleep_until(200_000_000)  # 0.8 s behind: no wait, the pace starts again from here
    c.sleep_until(500_000_000)  # 0.3 s of simulated time later: 0.3 s of wall time
    assert wall.slept == [pytest.approx(0.3)]


def test_a_paced_simulated_clock_catches_up_a_small_lag(wall: FakeWall) -> None:
    c = SimulatedClock(realtime=True)
    wall.ns += 250_000_000
    c.sleep_until(200_000_000)  # 50 ms behind: kept, the next waits make it up
    c.sleep_until(500_000_000)
    assert wall.slept == [pytest.approx(0.25)]


def test_the_monotonic_clock_starts_near_zero() -> None:
    assert 0 <= MonotonicClock().now_ns() < 1_000_000_000
