"""Counted losses for the estimators outside the AHRS family (Freescale, the varios).

The pipeline counts the frames a device's stream produced and did not deliver and hands an
estimator that consumes :class:`~imuhal.core.gaps.StreamGap` one just before the frame
delivered after the loss (imuhal.core.gaps). A long step between two time stamps is then
either real time in which frames were lost (a gap ends at that frame) or a time stamp that
jumped (nothing explains it). :class:`CountedGaps` tells them apart the way the AHRS family
does (imuhal_filters.common.ahrs): a step over a counted loss up to ``max_gap_s`` is
integrated or predicted over its true interval; beyond that bound, or over a step nobody
explained, the filter restarts from the new sample rather than trust its model across it.
"""

from __future__ import annotations

from collections.abc import Collection
from enum import Enum

from imuhal.core.gaps import StreamGap
from imuhal.core.quantities import Quantity


class Step(Enum):
    """What an estimator does with the step from its previous frame to this one."""

    NORMAL = "normal"
    """Within ``max_dt_s``: an ordinary step."""
    OVER_GAP = "over_gap"
    """A counted loss of at most ``max_gap_s`` ends at this frame: step over its span."""
    RESTART = "restart"
    """A counted loss longer than ``max_gap_s``, or a step longer than ``max_dt_s`` that no
    counted loss explains: start again from this frame."""


class CountedGaps:
    """The counted losses of the streams an estimator steps on (``streams``)."""

    def __init__(self, streams: Collection[Quantity]) -> None:
        self._streams = frozenset(streams)
        self._at_ns: int | None = None

    def note(self, gap: StreamGap) -> None:
        """A gap the pipeline handed over: it ends at the frame stamped ``gap.t_ns``."""
        if gap.stream in self._streams:
            self._at_ns = gap.t_ns

    def explained(self, t_ns: int) -> bool:
        """A counted loss ends at the frame stamped ``t_ns``."""
        return t_ns == self._at_ns

    def step(self, t_ns: int, step_s: float, max_dt_s: float, max_gap_s: float) -> Step:
        """The kind of a positive step of ``step_s`` seconds ending at the frame ``t_ns``."""
        if step_s <= max_dt_s:
            return Step.NORMAL
        if self.explained(t_ns) and step_s <= max_gap_s:
            return Step.OVER_GAP
        return Step.RESTART

    def forget(self) -> None:
        """After a restart or a reset."""
        self._at_ns = None
