"""``imuhal replay --realtime``: the pace sink holds each event back to its recorded time on
the wall clock (a fake clock here: no timed test)."""

from __future__ import annotations

from dataclasses import dataclass

import pytest

from imuhal.offline.replay import WallClockPace


@dataclass
class _Event:
    t_ns: int


class _FakeClock:
    """A monotonic clock that moves only when slept on, or by ``work_s`` (decoding time)."""

    def __init__(self) -> None:
        self.now_s = 100.0
        self.slept: list[float] = []

    def monotonic(self) -> float:
        return self.now_s

    def sleep(self, seconds: float) -> None:
        self.slept.append(seconds)
        self.now_s += seconds


def test_each_event_is_handed_on_when_its_recorded_time_has_passed_on_the_wall_clock() -> None:
    clock = _FakeClock()
    pace = WallClockPace(clock.monotonic, clock.sleep)
    for t_s in (5.0, 5.01, 5.03, 6.0):
        pace.handle(_Event(int(t_s * 1e9)))
    assert clock.slept == pytest.approx([0.01, 0.02, 0.97])
    assert clock.now_s == pytest.approx(101.0)  # 1 s of recorded time took 1 s


def test_an_event_decoded_late_is_handed_on_at_once_and_the_pace_does_not_drift() -> None:
    clock = _FakeClock()
    pace = WallClockPace(clock.monotonic, clock.sleep)
    pace.handle(_Event(0))
    clock.now_s += 0.5  # decoding the next events took 0.5 s of wall time
    pace.handle(_Event(200_000_000))  # due 0.2 s after the first: late, no wait
    pace.handle(_Event(1_000_000_000))  # due at 1.0 s: waits the 0.5 s left, not 0.8 s
    assert clock.slept == pytest.approx([0.5])
