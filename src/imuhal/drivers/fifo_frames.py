"""Time stamps and hand-out of frames read in bursts from a chip's FIFO (issue 25).

What every FIFO reader shares, whatever its chip: frames are placed on the chip's own clock
(imuhal.drivers.chip_clock: the host's clock read just before and just after each count
bounds the chip's period and phase), or paired with the chip's data-ready edges when a line
triggers the reads (imuhal.drivers.edge_stamps); frames read before either places them are
held (nothing is lost) and handed out once placed, at the latest when the run ends
(:meth:`drain`, only those the estimate places). A chip's reader (the MPU-9250's, the
MAX21100's) does the register work: it reads the count, decides whether the FIFO
overflowed or a burst is corrupt, reads whole frames, resets the FIFO, and hands the
frames to :meth:`FifoFrames.took` or calls :meth:`FifoFrames.dropped`.
Nothing here knows a chip.
"""

from __future__ import annotations

from dataclasses import dataclass

from imuhal.core.clock import Clock
from imuhal.drivers.chip_clock import ChipClock
from imuhal.drivers.edge_stamps import EdgeStamps

DROP_PLACED_FRACTION = 0.01
"""Held frames go out at a FIFO reset when the estimate places them this well (of a
period: 50 us at 200 Hz)."""
HOLD_MAX_FRAMES = 400
"""Frames held back at most while the chip's clock is learned (2 s at 200 Hz); then they
go out stamped with the estimate as it stands."""
EDGE_WAIT_FRAMES = 4
"""Frames that may wait for their data-ready edges (frames the chip wrote after the host
took its edges, a period or two) before the line counts as silent."""
READY_FRACTION = 0.002
"""Frames go out once the chip's clock places them to this fraction of a period."""


@dataclass(frozen=True)
class FifoRead:
    """One read's outcome: frames (oldest first, the chip's bytes of each) with their time
    stamps (ns, pipeline clock), and whether the FIFO was reset (an overflow or a corrupt
    burst: its frames are lost)."""

    frames: list[bytes]
    stamps_ns: list[int]
    reset: bool = False
    held: int = 0
    """Frames read and kept back until the chip's clock is learned (the chip works)."""


class FifoFrames:
    """Stamps and hands out the frames a chip's FIFO reader took (module docstring)."""

    def __init__(self, period_ns: int, clock: Clock) -> None:
        self.clock = clock
        self.period_ns = period_ns
        self.chip_clock = ChipClock(period_ns, ready_fraction=READY_FRACTION)
        self.edges = EdgeStamps(period_ns, wait_frames=EDGE_WAIT_FRAMES)
        self._held: list[tuple[int, bytes]] = []
        """Frames (index on the chip's clock, bytes) read but not yet handed out."""
        self._base_ns: int | None = None

    def cleared(self, requested_ns: int, *, restart: bool,
                same_oscillator: bool = False) -> None:
        """The chip's FIFO was emptied, requested at ``requested_ns`` (host clock, read
        before the request). ``restart``: the chip's sampling restarted too (configured),
        so the frames held and the clock phase learned belong to a configuration gone;
        ``same_oscillator``: at the period it had (ChipClock.restart)."""
        if restart:
            self._held = []
            if same_oscillator:  # the reads' schedule starts again at the restart
                self._base_ns = None
            self.chip_clock.restart(same_oscillator=same_oscillator)
            self.edges.restarted(requested_ns)
        else:
            self.chip_clock.frames_dropped()
            self.edges.cleared(requested_ns)

    def data_ready(self, times_ns: list[int]) -> None:
        """Data-ready edges of the chip's INT line (pipeline clock, oldest first)."""
        self.edges.add(times_ns)

    def _on_edges(self) -> bool:
        """Frames are stamped from edges: the line is on, or was and stamps go on from it."""
        return self.edges.on_line or self.edges.anchored

    def next_read_ns(self, now_ns: int, interval_ns: int) -> int:
        """When to read next: about ``interval_ns`` on from the previous read's slot, where
        the read tells most about the chip's clock (``ChipClock.probe_ns``)."""
        if self.chip_clock.relearning():
            # after a reset at the period it had, only the phase is learned: a bisection
            # of about ten reads, one a period (40 ms at 250 Hz) where ``interval_ns``
            # apart it took longer than resets 0.4 s apart left (the fault matrix at 1 %);
            # the reads ``interval_ns`` apart start from the read after
            self._base_ns = None
            return max(self.chip_clock.probe_ns(now_ns + self.period_ns // 2), now_ns + 1)
        base = now_ns if self._base_ns is None else self._base_ns + interval_ns
        base = max(base, now_ns - self.period_ns)
        self._base_ns = base
        return max(self.chip_clock.probe_ns(base + interval_ns), now_ns + 1)

    def took(self, frames: list[bytes], lo_ns: int, hi_ns: int) -> FifoRead:
        """``frames``: every whole frame the FIFO held at a count read between ``lo_ns``
        and ``hi_ns`` (host clock), oldest first. What can be stamped goes out."""
        n = len(frames)
        newest = self.chip_clock.observe(n, lo_ns, hi_ns)
        self._held += [(newest - n + 1 + i, f) for i, f in enumerate(frames)]
        if self._on_edges():
            return self._release_on_edges()
        if not self._held or (not self.chip_clock.settled()
                              and len(self._held) < HOLD_MAX_FRAMES):
            return FifoRead([], [], held=len(self._held))
        return self._release()

    def _release(self, *, reset: bool = False) -> FifoRead:
        """The held frames, stamped with the estimate as it stands."""
        held, self._held = self._held, []
        if self.edges.last_ns is not None:
            self.chip_clock.continue_after(self.edges.last_ns)
        stamps = self.chip_clock.stamps([k for k, _ in held])
        return FifoRead([f for _, f in held], stamps, reset=reset)

    def _release_on_edges(self, *, final: bool = False, reset: bool = False) -> FifoRead:
        """The held frames that have their edges, each stamped with its own; ``final``
        (a reset or the run's end: no edge will be waited for) or a silent line: the rest
        one learned period after the stamp before."""
        held = self._held
        stamps = self.edges.match(len(held), every_frame_read=not final)
        waiting = len(held) - len(stamps)
        if waiting > self.edges.wait_frames:
            self.edges.silent()
        if waiting and (final or not self.edges.on_line) and self.edges.anchored:
            stamps += self.edges.extrapolate(waiting)
        out, self._held = held[:len(stamps)], held[len(stamps):]
        if final and self._held:  # no edge to go on from: the read-time estimate's stamps
            rest = self._release()
            return FifoRead([f for _, f in out] + rest.frames, stamps + rest.stamps_ns,
                            reset=reset)
        return FifoRead([f for _, f in out], stamps, reset=reset, held=len(self._held))

    def drain(self) -> FifoRead:
        """Every frame held (the run ends): stamped from its edge when it came, else with
        the estimate when it places them as :meth:`dropped` asks; frames it does not place
        stay unread (the run ended before they were: handed out, a restart's unsettled
        phase stamped them up to 2.3 ms off)."""
        if self._on_edges():
            return self._release_on_edges(final=True)
        placed = self.chip_clock.uncertainty_ns() <= DROP_PLACED_FRACTION * self.period_ns
        return self._release() if self._held and placed else FifoRead([], [])

    def dropped(self, kept: list[bytes] | None = None) -> FifoRead:
        """The chip's FIFO is about to be reset (an overflow or a corrupt burst). Frames
        held from earlier reads, and ``kept`` (the frames a FIFO that stopped writing when
        full kept, read whole: the oldest since the last read, in order), go out now when
        the data-ready edges or the estimate place them to ``DROP_PLACED_FRACTION`` of a
        period (their count ends here); otherwise they are lost with the FIFO's, never
        handed out with a wrong stamp. The caller resets the FIFO and then calls
        :meth:`cleared` (``restart=False``)."""
        if kept:
            newest = self.chip_clock.continued(len(kept))
            self._held += [(newest - len(kept) + 1 + i, f) for i, f in enumerate(kept)]
        placed = self.chip_clock.uncertainty_ns() <= DROP_PLACED_FRACTION * self.period_ns
        if self._on_edges():
            out = self._release_on_edges(final=True, reset=True)
        else:
            out = self._release(reset=True) if placed else FifoRead([], [], reset=True)
        self._held = []
        return out
