"""When a hardware board says its polls happen (imuhal.pipeline.board.HardwareBoard)."""

from imuhal.core.clock import SimulatedClock
from imuhal.pipeline.board import HELD_POLL_NS, HardwareBoard


def test_a_poll_woken_a_little_late_keeps_its_due_time() -> None:
    clock = SimulatedClock(10_000_000 + 80_000)  # 80 us of wake-up latency
    board = HardwareBoard({}, clock)
    assert board.before_poll(10_000_000, "imu") == 10_000_000


def test_a_poll_the_thread_was_held_past_is_stamped_when_it_happens() -> None:
    due_ns = 10_000_000
    clock = SimulatedClock(due_ns + HELD_POLL_NS + 40_000_000)  # another device held 40 ms
    board = HardwareBoard({}, clock)
    assert board.before_poll(due_ns, "baro") == clock.now_ns()
