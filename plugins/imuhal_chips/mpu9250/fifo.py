"""Reading the MPU-9250's FIFO (``read: fifo``): whole frames, overflow as a counted loss and
a reset, a corruption check, frames stamped on the chip's own clock.

Register facts: MPU-9250 Register Map rev 1.4 and imuhal's shared chip facts, section 4
"FIFO" (PX4 MPU9250.cpp and Linux inv_mpu_ring.c read it the same way). The FIFO holds
accel, temperature and gyro (FIFO_EN 0xF8): 14 bytes in register order, big-endian, the
same bytes as a 0x3B..0x48 burst; with a slave auto-read (the AK8963 on slave 0) FIFO_EN
also sets SLV0 and each frame ends with the slave's LENG bytes as slave 0 copied them at
that sample (EXT_SENS_DATA order): 22-byte frames with the AK8963's ST1..ST2, 23 frames.

- **Count, then whole frames.** FIFO_COUNTH/L first; then ``count // frame_bytes`` frames
  in one burst from FIFO_R_W. Frames the chip appends between the count and the burst stay
  for the next read (the count-to-read race costs nothing: the burst never reads past the
  count).
- **Overflow.** CONFIG.FIFO_MODE 0 (the power-on mode: the oldest bytes are overwritten) loses
  the frame boundary, so a count with fewer than ``OVERFLOW_MARGIN_FRAMES`` frames of room
  left, or FIFO_OFLOW_INT, means the FIFO may have wrapped: it is reset
  (USER_CTRL.FIFO_RST) without being read and the frames it held are lost, counted in the
  driver's ``health.fifo_overflows`` (the pipeline's ledger charges them to
  ``fifo_overflow``).
- **Corruption check.** The die temperature cannot move by ``TEMPERATURE_JUMP_DEGC`` between
  two frames 1 ms or less apart (ArduPilot's test); a jump means the frames are shifted
  (a lost or extra byte): the FIFO is reset and the burst dropped, counted as an overflow.
- **Time stamps from the chip's clock** (imuhal.drivers.chip_clock): the host's clock is
  read just before and just after each count; the count says which frames the chip had
  measured by then, so every read bounds the chip's period and phase whatever the host's
  delays. The reads are spread over the chip's period (``next_read_ns``), the estimate
  narrows to microseconds within a second, and each frame is stamped with its estimated
  measurement instant, smoothed (never back, at most 5 % of a period off one period after
  the previous stamp). Frames read before the estimate places them to 0.2 % of a period
  are held back (at most ``HOLD_MAX_FRAMES``, kept in the driver, so nothing is lost) and
  handed out stamped once it does.
- **Time stamps from data-ready edges** (a profile's ``interrupt:`` line on the chip's INT
  pin, RAW_RDY_EN: one edge per sample; imuhal.drivers.edge_stamps): each frame is stamped
  with its own edge's kernel time stamp, as Linux's inv_sensors_timestamp.c stamps FIFO
  frames from interrupt times, however many edges go to one read; the read-time estimate
  above is not needed then. Frames whose edge has not come yet wait in the reader (at most
  ``EDGE_WAIT_FRAMES``; more means the line went silent: they go on one learned period
  after the previous stamp). ``drain()`` hands out what is held when a run ends.
"""

from __future__ import annotations

from dataclasses import dataclass
from itertools import pairwise

from imuhal.bus.registers import RegisterView
from imuhal.core.clock import Clock
from imuhal.drivers.chip_clock import ChipClock
from imuhal.drivers.edge_stamps import EdgeStamps
from imuhal_chips.mpu9250 import registers as r
from imuhal_chips.mpu9250.decode import decode_counts, temperature_degc

FRAME_BYTES = 14
"""ACCEL_XOUT_H..GYRO_ZOUT_L: accel (6), temperature (2), gyro (6); a slave's bytes follow."""
FIFO_EN_VALUE = r.FIFO_TEMP | r.FIFO_GYRO_X | r.FIFO_GYRO_Y | r.FIFO_GYRO_Z | r.FIFO_ACCEL
OVERFLOW_MARGIN_FRAMES = 2
"""Reset when fewer than this many frames of room are left (Linux inv_mpu_ring.c keeps 3
of its frames; with the AK8963's bytes the FIFO holds only 23, so imuhal keeps 2: a count
read with two frames of room cannot have wrapped, and the burst reads no further than the
count)."""
TEMPERATURE_JUMP_DEGC = 2.0
"""A larger step of the die temperature between consecutive frames is no measurement."""
DROP_PLACED_FRACTION = 0.01
"""Held frames go out at a FIFO reset when the estimate places them this well (of a
period: 50 us at 200 Hz)."""
HOLD_MAX_FRAMES = 400
"""Frames held back at most while the chip's clock is learned (2 s at 200 Hz); then they
go out stamped with the estimate as it stands."""
EDGE_WAIT_FRAMES = 4
"""Frames that may wait for their data-ready edges (frames the chip wrote after the host
took its edges, a period or two) before the line counts as silent."""


@dataclass(frozen=True)
class FifoRead:
    """One read's outcome: frames (oldest first, ``frame_bytes`` each: 14 bytes of accel,
    temperature and gyro, then the slave's bytes) with their time stamps, and whether the
    FIFO was reset (an overflow or a corrupt burst: its frames are lost)."""

    frames: list[bytes]
    stamps_ns: list[int]
    reset: bool = False
    held: int = 0
    """Frames read and kept back until the chip's clock is learned (the chip works)."""


def frames_consistent(frames: list[bytes]) -> bool:
    """False when the temperature jumps by more than TEMPERATURE_JUMP_DEGC between two
    consecutive frames (a shifted burst)."""
    temps = [temperature_degc(decode_counts(f[:FRAME_BYTES]).temperature) for f in frames]
    return all(abs(b - a) <= TEMPERATURE_JUMP_DEGC for a, b in pairwise(temps))


class FifoReader:
    """Reads whole frames from the FIFO of one MPU-9250 (see the module docstring).
    ``slave_bytes``: slave 0's LENG when its bytes are in the FIFO (FIFO_EN.SLV0)."""

    def __init__(self, regs: RegisterView, period_ns: int, clock: Clock, *,
                 slave_bytes: int = 0) -> None:
        self.regs = regs
        self.clock = clock
        self.period_ns = period_ns
        self.frame_bytes = FRAME_BYTES + slave_bytes
        self.overflow_at = r.FIFO_SIZE_BYTES - OVERFLOW_MARGIN_FRAMES * self.frame_bytes
        self.chip_clock = ChipClock(period_ns, ready_fraction=0.002)
        self.edges = EdgeStamps(period_ns, wait_frames=EDGE_WAIT_FRAMES)
        self._held: list[tuple[int, bytes]] = []
        """Frames (index, bytes) read before the chip's clock was learned."""
        self._base_ns: int | None = None

    @property
    def depth_frames(self) -> int:
        """Whole frames the FIFO holds."""
        return r.FIFO_SIZE_BYTES // self.frame_bytes

    def reset(self, user_ctrl: int, *, restart: bool = True) -> None:
        """Empty the FIFO (USER_CTRL.FIFO_RST self-clears; the other bits rewritten).
        ``restart``: the chip's sampling restarted too (configured), not only its FIFO."""
        requested_ns = self.clock.now_ns()
        self.regs.write(r.USER_CTRL, user_ctrl | r.USER_FIFO_RST)
        if restart:
            self._held = []  # frames of the configuration before: their clock is gone
            self.chip_clock.restart()
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
        base = now_ns if self._base_ns is None else self._base_ns + interval_ns
        base = max(base, now_ns - self.period_ns)
        self._base_ns = base
        return max(self.chip_clock.probe_ns(base + interval_ns), now_ns + 1)

    def read(self, user_ctrl: int, *, overflowed: bool) -> FifoRead:
        """Count, check for overflow, read whole frames. ``overflowed``: INT_STATUS said
        FIFO_OFLOW_INT."""
        lo_ns = self.clock.now_ns()
        high, low = self.regs.read(r.FIFO_COUNTH, 2)
        hi_ns = self.clock.now_ns()
        count = (high & 0x1F) << 8 | low
        if overflowed or count > self.overflow_at:
            return self._drop(user_ctrl)
        n = count // self.frame_bytes
        frames: list[bytes] = []
        if n:
            size = self.frame_bytes
            data = self.regs.read(r.FIFO_R_W, n * size)
            frames = [data[i * size:(i + 1) * size] for i in range(n)]
            if not frames_consistent(frames):
                return self._drop(user_ctrl)
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
        """Every frame held (the run ends): stamped from its edge when it came, else as the
        stamps before it go on."""
        if self._on_edges():
            return self._release_on_edges(final=True)
        return self._release() if self._held else FifoRead([], [])

    def _drop(self, user_ctrl: int) -> FifoRead:
        """An overflow or a corrupt burst: the FIFO is reset unread. Frames held from
        earlier reads go out now when the estimate places them to ``DROP_PLACED_FRACTION``
        of a period (their count ends here); otherwise they are lost with the FIFO's, never
        handed out with a wrong stamp."""
        placed = self.chip_clock.uncertainty_ns() <= DROP_PLACED_FRACTION * self.period_ns
        if self._on_edges():
            out = self._release_on_edges(final=True, reset=True)
        else:
            out = self._release(reset=True) if placed else FifoRead([], [], reset=True)
        self._held = []
        self.reset(user_ctrl, restart=False)
        return out
