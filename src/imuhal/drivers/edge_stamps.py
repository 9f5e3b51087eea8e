"""Time stamps of buffered frames from the chip's data-ready edges (issue 25 item 4).

A chip that raises its data-ready (INT) pin at every sample and also buffers the sample in
its FIFO gives the host one edge per frame; the kernel stamps each edge when the interrupt
comes (libgpiod's event time stamp: microseconds after the chip's own instant, never before
it). Reading the FIFO only every few edges (a watermark) then still leaves every frame with
its own time stamp: frames and edges pair up in order. This is what Linux's
``inv_sensors_timestamp.c`` does with its interrupt times (the interrupt's time for the
newest frame, the older ones back-dated by the period learned from the interrupts); here
each frame has its own edge, so none is back-dated unless its edge is missing.

The pairing, for a reader that takes its edges before each read of the FIFO's count and
reads every whole frame counted:

- **Every queued edge's frame is in the FIFO** at the count (the chip raises the edge after
  writing the frame). More edges than frames are edges of frames a FIFO reset cleared
  (an edge that came between the reset's request and its effect): the oldest ones go.
- **Fewer edges than frames**: the newest frames came after the edges were taken. They wait
  in the reader for their edges (at most ``wait_frames``); a longer wait means the line
  went silent (a chip that lost its interrupt configuration, a line the host missed): the
  frames are then stamped one learned period after the previous stamp (:meth:`extrapolate`)
  and, when edges come back, the frames older than the first returning edge are back-dated
  from it (:meth:`match` with ``newest=True``).
- **Edges the kernel did not queue** (a gap in the line's sequence numbers) are filled by
  the pipeline, evenly between their neighbours, before they reach a driver.
- **Stamps never go back**: each is at least one nanosecond after the one before.

The period (:attr:`period_ns`) is learned from the edges paired with frames, the span of up
to ``window`` consecutive edges over their count, limited to ``tolerance`` of the datasheet
period (Linux's jitter bound). Nothing here knows a chip.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Iterable


class EdgeStamps:
    """Pairs a chip's data-ready edges (times on the pipeline's clock, ns) with its buffered
    frames, oldest first (see the module docstring)."""

    def __init__(self, nominal_period_ns: int, *, tolerance: float = 0.05,
                 window: int = 64, wait_frames: int = 4) -> None:
        if nominal_period_ns <= 0:
            raise ValueError(f"period must be positive, got {nominal_period_ns} ns")
        self.nominal_period_ns = nominal_period_ns
        self.tolerance = tolerance
        self.wait_frames = wait_frames
        """Frames that may wait for their edges before the line counts as silent."""
        self.on_line = False
        """Edges have come since the reader's last restart and the line is not silent."""
        self.last_ns: int | None = None
        """The latest stamp handed out."""
        self.surplus_edges = 0
        """Edges dropped because no frame was left for them (a FIFO reset's)."""
        self._queued: deque[int] = deque()
        self._recent: deque[int] = deque(maxlen=window)
        self._not_before_ns: int | None = None
        self._skip = 0
        self._returning = False

    # -- edges ------------------------------------------------------------------------------

    def add(self, times_ns: Iterable[int]) -> None:
        """Edges of the chip's line, oldest first (a gap already filled)."""
        for t in times_ns:
            if self._not_before_ns is not None and t < self._not_before_ns:
                continue  # the edge of a frame a FIFO reset cleared
            if self._skip:
                self._skip -= 1  # the edge of a frame already handed out without it
                continue
            if not self.on_line:
                self.on_line = True
                self._returning = self.last_ns is not None
            self._queued.append(t)

    def cleared(self, from_ns: int) -> None:
        """The FIFO was emptied at or after ``from_ns`` (host clock, read before the reset
        was requested): edges before it are of frames it cleared."""
        self._queued.clear()
        self._recent.clear()
        self._skip = 0
        self._not_before_ns = from_ns

    def restarted(self, from_ns: int) -> None:
        """The chip was reconfigured (its interrupt configuration written again): as
        :meth:`cleared`; the line is awaited anew."""
        self.cleared(from_ns)
        self.on_line = False
        self._returning = False

    def silent(self) -> None:
        """Frames waited longer than ``wait_frames`` for their edges: the line is silent
        until edges come again."""
        self.on_line = False

    # -- stamps -----------------------------------------------------------------------------

    @property
    def period_ns(self) -> float:
        """The chip's period learned from its edges (the datasheet's before two)."""
        nominal = float(self.nominal_period_ns)
        if len(self._recent) < 2:
            return nominal
        learned = (self._recent[-1] - self._recent[0]) / (len(self._recent) - 1)
        return max(nominal * (1 - self.tolerance), min(nominal * (1 + self.tolerance), learned))

    def _hand_out(self, t_ns: float, *, edge: bool) -> int:
        stamp = round(t_ns)
        if self.last_ns is not None:
            stamp = max(stamp, self.last_ns + 1)
        self.last_ns = stamp
        if edge:
            self._recent.append(stamp)
        return stamp

    @property
    def anchored(self) -> bool:
        """A frame was paired with its edge since the last FIFO reset: frames can be
        stamped on from it (:meth:`extrapolate`)."""
        return bool(self._recent)

    def match(self, n: int, *, every_frame_read: bool = True) -> list[int]:
        """Stamps for the oldest of ``n`` frames in hand, from the queued edges: one per
        frame while edges last (the rest wait); after a silence, the frames older than the
        first returning edge are back-dated from it one learned period each.
        ``every_frame_read``: the ``n`` frames are all the FIFO held when the edges were
        taken, so edges beyond them are a reset's (dropped); False: frames are still in
        the FIFO (a reset about to clear them, the end of a run) and keep their edges."""
        surplus = len(self._queued) - n if every_frame_read else 0
        for _ in range(max(0, surplus)):
            self._queued.popleft()
            self.surplus_edges += 1
        out: list[int] = []
        if self._returning and self._queued and len(self._queued) < n:
            first = self._queued[0]
            older = n - len(self._queued)
            p = self.period_ns
            out = [self._hand_out(first - (older - i) * p, edge=False) for i in range(older)]
        self._returning = False
        while self._queued and len(out) < n:
            out.append(self._hand_out(self._queued.popleft(), edge=True))
        return out

    def extrapolate(self, n: int) -> list[int]:
        """Stamps for ``n`` frames whose edges will not be waited for (a silent line, the
        end of a run): one learned period after the stamp before each. Their edges, should
        they still come while the line is on, are dropped. Call it with no edge queued
        (after :meth:`match`) and after at least one stamp."""
        if self.last_ns is None:
            raise ValueError("no stamp to extrapolate from: match an edge first")
        p = self.period_ns
        out: list[int] = []
        for _ in range(n):
            out.append(self._hand_out(self.last_ns + p, edge=False))
        if self.on_line:
            self._skip += n
        return out
