"""Losses as gaps the estimators see (issue 25 item 5).

When the pipeline counts frames a device's stream produced and did not deliver
(imuhal.pipeline.accounting: a host stall, a bus error, a reset, a FIFO overflow...), the
next frame it delivers is preceded, on the estimators' path, by a :class:`StreamGap`: which
stream lost how many frames, from which frame's time stamp to which, and why. An estimator
that lists ``StreamGap`` in its ``consumes`` gets it just before that frame (fusion order
puts a gap first among the items of its instant), so it knows that a long step between two
time stamps is real time in which data was lost, not a time stamp that jumped: it can
integrate over the true interval, and refuse to integrate over a step nobody explained.

Gaps go to estimators only; sinks and ``Pipeline.events()`` see the run summary's counts
(``RunSummary.frames``), not one event per gap.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

from imuhal.core.quantities import Quantity
from imuhal.core.samples import Sample

GAP = Quantity("gap", "frame", description="frames a stream produced and did not deliver")
"""The quantity of a :class:`StreamGap` (it measures nothing: it says what is missing)."""


@dataclass(frozen=True, slots=True, kw_only=True)
class StreamGap(Sample):
    """Frames of ``device``'s ``stream`` lost between two frames it delivered: the one
    stamped ``last_ns`` and the one stamped ``t_ns`` (this item's time), which this gap
    precedes. Never flagged: a gap is a fact."""

    stream: Quantity
    """The quantity of the accounted stream that lost frames (the device's other streams
    came in the same reads and lost the same frames)."""
    frames: int
    """Frames lost (at least 1)."""
    last_ns: int
    """The time stamp of the last frame delivered before the loss (ns)."""
    cause: str
    """The weightiest cause seen in the gap (imuhal.pipeline.accounting.CAUSES)."""
    channel: ClassVar[Quantity] = GAP

    @property
    def span_ns(self) -> int:
        """The true interval between the frames around the gap (ns)."""
        return self.t_ns - self.last_ns
