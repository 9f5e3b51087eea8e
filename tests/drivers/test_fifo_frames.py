"""imuhal.drivers.fifo_frames: frames held while the chip's clock is learned never go out
with a stamp the estimate does not place."""

from __future__ import annotations

from imuhal.core.clock import SimulatedClock
from imuhal.drivers.fifo_frames import FifoFrames

PERIOD_NS = 4_000_000


def test_frames_held_at_the_run_end_go_out_only_when_the_estimate_places_them() -> None:
    """One read after a restart places its frames within a period only: the drain keeps
    them (handed out, they were stamped up to a period off)."""
    frames = FifoFrames(PERIOD_NS, SimulatedClock())
    frame = bytes(12)
    held = frames.took([frame] * 8, 40_000_000, 40_050_000)
    assert held.frames == [] and held.held == 8
    assert frames.drain().frames == []
