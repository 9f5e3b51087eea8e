"""Time stamps from a chip's own clock for frames read in bursts (a FIFO), from the host's
read times, robust to any host delay.

A chip that buffers its samples measures frame ``k`` at ``T(k) = A + k * P`` on its own
oscillator (``P`` within a tolerance of the datasheet period). The host does not see those
instants; it sees, at each read of the FIFO's count, which frames were there. A read whose
count was taken after the host clock read ``lo_ns`` and before it read ``hi_ns`` and found
the newest frame to be ``k`` says exactly two things, whatever the host's delays were:

- frame ``k`` had been measured by ``hi_ns``: ``A + k P <= hi_ns``;
- frame ``k + 1`` had not been measured at ``lo_ns``: ``A + (k + 1) P > lo_ns``.

A late read (a stalled host, a slow bus) only weakens its two bounds; it never makes them
wrong, so no host jitter can pull the estimate (the idea Linux's inv_sensors_timestamp.c
applies to interrupt times, "learn the period within jitter bounds", here without an
interrupt line). Every pair of bounds is a half-plane in (A, P); :class:`ChipClock` keeps
their intersection, a convex polygon, and stamps frames with its centre. Reads at varied
phases of the chip's period shrink it: :meth:`ChipClock.probe_ns` places a reader's next
read where the estimate is least sure whether a frame is there yet (a bisection), and reads
spread over a longer time pin the period. When the bounds contradict each other (the
chip's oscillator drifted or stepped), the polygon is rebuilt from the reads of the last
``window_s``.

Stamps handed out are smoothed: each is one period estimate after the previous one,
corrected toward the estimate by at most ``max_step`` of a period (5 %: 250 us at 200 Hz),
so a stamp never goes back and never jumps: consecutive stamps lie between
``(1 - tolerance)(1 - max_step)`` and ``(1 + tolerance)(1 + max_step)`` nominal periods
apart, and within ``max_step`` of the true period once it is learned; frames the chip
measured while nothing was read (a FIFO reset) are a multiple of the period later. Until
the estimate is good to ``ready_fraction`` of a period a reader may hold frames back
(:meth:`ChipClock.settled`).
Nothing here knows a chip.
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Sequence
from dataclasses import dataclass


@dataclass(frozen=True)
class ClockRead:
    """One read of the chip's frame count: the newest frame ``k`` was there at the chip
    between host times ``lo_ns`` (before the count was read) and ``hi_ns`` (after)."""

    k: int
    lo_ns: int
    hi_ns: int


PERIOD_MEMORY = 0.001
"""How far the chip's period may have moved while a FIFO reset kept the host from
watching it (a fraction: far more than temperature drift does in a second)."""
RESTART_PERIOD_MEMORY = 0.0001
"""How far the chip's period may have moved between the last read that placed its frames
settled and a restart at the same period (a reset: well under a second without a read;
temperature drift moves a MEMS oscillator by a few parts in a million in that time)."""
PROBE_OFFSET_NS = 2_000
"""How far from the estimated instant of a frame a probe reads (either side, in turn): the
resolution the estimate keeps tracking a moving chip clock at."""

Vertex = tuple[float, float]
"""(A, the instant of frame 0 relative to ``ChipClock._origin_ns``, ns; P, the period, ns)."""


def _clip(polygon: list[Vertex], a: float, b: float, c: float) -> list[Vertex]:
    """The part of a convex polygon where ``a * A + b * P <= c`` (Sutherland-Hodgman)."""
    out: list[Vertex] = []
    n = len(polygon)
    # each vertex's side once (each edge's end is the next edge's start)
    side = [a * x + b * y - c for x, y in polygon]
    for i in range(n):
        j = i + 1 if i + 1 < n else 0
        p, q = polygon[i], polygon[j]
        fp, fq = side[i], side[j]
        if fp <= 0:
            out.append(p)
        if (fp < 0 < fq) or (fq < 0 < fp):
            s = fp / (fp - fq)
            out.append((p[0] + s * (q[0] - p[0]), p[1] + s * (q[1] - p[1])))
    return out


class ChipClock:
    """The measurement instants of one chip's frames, learned from count reads (see the
    module docstring). Frame indices count from the first frame after :meth:`restart`.

    ``nominal_period_ns``: the datasheet's period; ``tolerance``: how far the chip's
    oscillator may be off it (fraction); ``window_s``: how far back reads are kept to rebuild
    the estimate after the chip's clock moved; ``max_step``: the largest correction of one
    stamp, as a fraction of the period; ``ready_fraction``: how well (of a period) the
    newest frame must be placed for :meth:`settled`.
    """

    def __init__(self, nominal_period_ns: int, *, tolerance: float = 0.05,
                 window_s: float = 0.25, max_step: float = 0.05,
                 ready_fraction: float = 0.02) -> None:
        if not 0 < max_step < 0.5:
            raise ValueError(f"max_step {max_step} must lie between 0 and 0.5 of a period")
        self.nominal_period_ns = nominal_period_ns
        self.tolerance = tolerance
        self.window_ns = round(window_s * 1e9)
        self.max_step = max_step
        self.ready_fraction = ready_fraction
        self.rebuilds = 0
        """Times the bounds contradicted each other (the chip's clock moved)."""
        self._reads: deque[ClockRead] = deque()
        self._polygon: list[Vertex] = []
        self._centre_of: list[Vertex] | None = None
        """The polygon whose centre ``_centre_at`` is (asked at every read and stamp)."""
        self._centre_at: Vertex = (0.0, 0.0)
        self._origin_ns = 0
        self._k: int | None = None
        """The newest frame's index at the last read (None: unknown, after a restart or a
        FIFO reset)."""
        self._last: tuple[int, int] | None = None
        """(index, stamp) of the last frame stamped."""
        self._floor_ns: int | None = None
        """The last stamp before a restart: the next may not lie at or before it."""
        self._probes = 0
        self._period_bounds: tuple[float, float] | None = None
        """What the period was learned to be before a FIFO reset (ns), widened."""
        self._settled_periods: tuple[float, float] | None = None
        """The period's bounds (ns) at the last read that left the estimate settled: what
        :meth:`restart` keeps with ``same_oscillator``."""
        self._counted_periods: tuple[float, float] | None = None
        """The period's bounds (ns) at the last read that found frames (settled or not):
        what :meth:`restart` keeps with ``same_oscillator`` before anything settled."""
        self.keep_unsettled = True
        """A restart with ``same_oscillator`` before the estimate first settled keeps the
        period's bounds learnt so far (imuhal.core.poll_plan.FIFO_RESET_PLAN; False: a
        driver on an older plan, which learnt the period afresh)."""
        self._kept_period = False
        """The period's bounds are the ones a restart kept (dropped at a contradiction:
        the chip's oscillator was not what it had been)."""

    # -- segments ---------------------------------------------------------------------------

    def restart(self, *, same_oscillator: bool = False) -> None:
        """The chip restarted its sampling (reconfigured): a new clock phase; stamps still
        never go back. ``same_oscillator``: the chip restarted at the period it had (a reset
        and the same configuration): its oscillator ran on, so the period last learned
        settled, widened by ``RESTART_PERIOD_MEMORY``, bounds the new estimate, and only the phase
        is learned afresh (a bisection from the first read: about ten reads, where the
        period too took about thirty). Before the estimate first settled, the period's
        bounds as far as they were learned at the last read that found frames are kept
        instead (wider, but still what the reads proved; a read that found none may follow
        a reset not yet noticed, whose emptied FIFO says nothing true about the clock), so
        resets that come faster than the first learning takes narrow them segment by segment
        instead of each starting from ``tolerance``."""
        unsettled = self._counted_periods if self.keep_unsettled else None
        known = (self._settled_periods or unsettled) if same_oscillator else None
        self._reads.clear()
        self._polygon = []
        self._k = None
        self._period_bounds = None if known is None else (
            known[0] * (1 - RESTART_PERIOD_MEMORY), known[1] * (1 + RESTART_PERIOD_MEMORY))
        self._kept_period = known is not None
        self._restart_stamps()

    def _restart_stamps(self) -> None:
        """The next stamp is the estimate's, only after the last one handed out."""
        if self._last is not None:
            self._floor_ns = self._last[1]
        self._last = None

    def frames_dropped(self) -> None:
        """The FIFO was reset: an unknown number of frames are gone, the chip's clock ran
        on. Frames are counted afresh (a guess of how many were lost would mix two
        countings in one estimate); the period learned so far, widened by
        ``PERIOD_MEMORY``, bounds the new estimate."""
        periods = [v[1] for v in self._polygon]
        self.restart()
        if periods:
            self._period_bounds = (min(periods) * (1 - PERIOD_MEMORY),
                                   max(periods) * (1 + PERIOD_MEMORY))

    def continue_after(self, stamp_ns: int) -> None:
        """Another source (a data-ready edge) stamped a frame at ``stamp_ns``: the next
        stamp is the estimate's, only after it."""
        if self._last is not None and self._last[1] >= stamp_ns:
            return
        self._last = None
        self._floor_ns = stamp_ns if self._floor_ns is None else max(self._floor_ns, stamp_ns)

    # -- observations -----------------------------------------------------------------------

    def observe(self, n: int, lo_ns: int, hi_ns: int) -> int:
        """A read found ``n`` new frames (count taken between ``lo_ns`` and ``hi_ns``);
        returns the index of the newest."""
        k = n - 1 if self._k is None else self._k + n
        self._k = k
        read = ClockRead(k, lo_ns, hi_ns)
        self._reads.append(read)
        while self._reads and self._reads[0].hi_ns < hi_ns - self.window_ns:
            self._reads.popleft()
        if not self._polygon:
            self._rebuild(hi_ns)
            return k
        clipped = self._constrain(self._polygon, read)
        if len(clipped) < 3:
            self.rebuilds += 1
            if self._kept_period:  # the period kept does not hold: learn it afresh
                self._period_bounds, self._kept_period = None, False
            self._rebuild(hi_ns)
        else:
            self._polygon = clipped
            if n or self.settled():
                periods = [v[1] for v in clipped]
                bounds = (min(periods), max(periods))
                if n:
                    self._counted_periods = bounds
                if self.settled():
                    self._settled_periods = bounds
        return k

    def continued(self, n: int) -> int:
        """``n`` frames followed the newest counted, read without a count that bounds
        their instants (a FIFO that stopped writing when full: the count says what it
        kept, not what the chip measured); returns the index of the newest. The bounds are
        left as they are."""
        k = n - 1 if self._k is None else self._k + n
        self._k = k
        return k

    def _constrain(self, polygon: list[Vertex], read: ClockRead) -> list[Vertex]:
        lo = read.lo_ns - self._origin_ns
        hi = read.hi_ns - self._origin_ns
        polygon = _clip(polygon, 1.0, float(read.k), float(hi))
        return _clip(polygon, -1.0, -float(read.k + 1), -float(lo))

    def _box(self, t_ns: int, k: int) -> list[Vertex]:
        p_lo = self.nominal_period_ns * (1.0 - self.tolerance)
        p_hi = self.nominal_period_ns * (1.0 + self.tolerance)
        if self._period_bounds is not None:
            p_lo = max(p_lo, self._period_bounds[0])
            p_hi = min(p_hi, self._period_bounds[1])
        t = float(t_ns - self._origin_ns)
        span = (abs(k) + 2) * p_hi
        return [(t - span, p_lo), (t + span, p_lo), (t + span, p_hi), (t - span, p_hi)]

    def _rebuild(self, now_ns: int) -> None:
        """The polygon from the kept reads, newest first; a read that contradicts the newer
        ones (the clock moved since) ends the rebuild."""
        newest = self._reads[-1]
        self._origin_ns = newest.lo_ns
        polygon = self._box(newest.hi_ns, newest.k)
        for read in reversed(self._reads):
            clipped = self._constrain(polygon, read)
            if len(clipped) < 3:
                while self._reads[0] is not read:
                    self._reads.popleft()
                self._reads.popleft()
                break
            polygon = clipped
        self._polygon = polygon

    # -- estimate ---------------------------------------------------------------------------

    def _centre(self) -> Vertex:
        polygon = self._polygon
        if polygon is self._centre_of:  # the polygon is replaced, never changed in place
            return self._centre_at
        n = len(polygon)
        xs, ps = zip(*polygon, strict=True)
        self._centre_at = (sum(xs) / n, sum(ps) / n)
        self._centre_of = polygon
        return self._centre_at

    @property
    def period_ns(self) -> float:
        """The period estimate (the nominal one before any read)."""
        return self._centre()[1] if self._polygon else float(self.nominal_period_ns)

    def uncertainty_ns(self) -> float:
        """How far apart the estimate's bounds place the newest frame (ns)."""
        if not self._polygon or self._k is None:
            return math.inf
        k = self._k
        at = [a + k * p for a, p in self._polygon]
        return max(at) - min(at)

    def relearning(self) -> bool:
        """Since a restart that kept the period (``same_oscillator``), the phase is not yet
        settled."""
        return self._kept_period and not self.settled()

    def settled(self) -> bool:
        """The newest frame is placed to within ``ready_fraction`` of a period."""
        return self.uncertainty_ns() <= self.ready_fraction * self.nominal_period_ns

    def instant_ns(self, k: int) -> float:
        """The estimated measurement instant of frame ``k`` (ns, host clock)."""
        a, p = self._centre()
        return self._origin_ns + a + k * p

    def stamps(self, indices: Sequence[int]) -> list[int]:
        """Smoothed stamps of frames ``indices`` (ascending; see the module docstring):
        never back, each within ``max_step`` of a period of the period estimate times the
        frames since the one stamped before."""
        # the estimate once for all frames (what period_ns and instant_ns give)
        a, p = self._centre() if self._polygon else (0.0, float(self.nominal_period_ns))
        base = self._origin_ns + a
        step = self.max_step * p
        out: list[int] = []
        if not indices:
            return out
        last = self._last
        if last is None:
            k0 = indices[0]
            s0 = round(base + k0 * p)  # instant_ns(k)
            if self._floor_ns is not None:
                s0 = max(s0, self._floor_ns + 1)
            out.append(s0)
            rest = indices[1:]
        else:
            k0, s0 = last
            rest = indices
        # the smoothing written out (every FIFO frame is stamped here): the same floats as
        # round(carried + max(-step, min(step, target - carried))), never before s0 + 1
        low = -step
        for k in rest:
            gap = k - k0
            carried = s0 + (gap if gap > 1 else 1) * p
            d = base + k * p - carried  # target - carried
            if not d <= step:  # (a NaN too, as min(step, d) gives step)
                d = step
            elif d < low:
                d = low
            stamp = round(carried + d)
            s0 = stamp if stamp > s0 else s0 + 1
            k0 = k
            out.append(s0)
        self._last = (k0, s0)
        return out

    def probe_ns(self, around_ns: int) -> int:
        """When to read the count next, near ``around_ns``: at the middle of the range the
        estimate allows for the instant of the frame due nearest to it, so the read finds
        that frame either there or not and halves the range (a bisection: from a period
        to microseconds in about ten reads). Before any read: ``around_ns``."""
        if not self._polygon:
            return around_ns
        a, p = self._centre()
        k = round((around_ns - self._origin_ns - a) / p)
        at = [v[0] + k * v[1] for v in self._polygon]
        # a little before or after the middle, in turn: a read exactly at an instant the
        # estimate is sure of agrees with it whichever way the chip's clock moved; one a
        # probe offset away on either side shows the move
        self._probes += 1
        offset = PROBE_OFFSET_NS if self._probes % 2 else -PROBE_OFFSET_NS
        return self._origin_ns + round((max(at) + min(at)) / 2) + offset
