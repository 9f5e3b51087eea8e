"""Reading the MPU-9250's FIFO (``read: fifo``): whole frames, overflow as a counted loss and
a reset, a corruption check, frames back-dated from the read time by the chip's period.

Register facts: MPU-9250 Register Map rev 1.4 and imuhal's shared chip facts, section 4
"FIFO" (PX4 MPU9250.cpp and Linux inv_mpu_ring.c read it the same way). The FIFO holds
accel, temperature and gyro (FIFO_EN 0xF8): 14-byte frames in register order, big-endian,
the same bytes as a 0x3B..0x48 burst.

- **Count, then whole frames.** FIFO_COUNTH/L first; then ``count // 14`` frames in one
  burst from FIFO_R_W. Frames the chip appends between the count and the burst stay for the
  next read (the count-to-read race costs nothing: the burst never reads past the count).
- **Overflow.** CONFIG.FIFO_MODE 0 (the power-on mode: the oldest bytes are overwritten) loses
  the frame boundary, so a count with fewer than ``OVERFLOW_MARGIN_FRAMES`` frames of room
  left (Linux's rule), or FIFO_OFLOW_INT, means the FIFO may have wrapped: it is reset
  (USER_CTRL.FIFO_RST) without being read and the frames it held are lost, counted in the
  driver's ``health.fifo_overflows`` (the pipeline's ledger charges them to
  ``fifo_overflow``).
- **Corruption check.** The die temperature cannot move by ``TEMPERATURE_JUMP_DEGC`` between
  two frames 1 ms or less apart (ArduPilot's test); a jump means the frames are shifted
  (a lost or extra byte): the FIFO is reset and the burst dropped, counted as an overflow.
- **Time stamps.** Each frame is a period after the one before. The first read stamps its
  newest frame with the read time; later reads continue the previous read's stamps
  (``t_last + k * period``) while that places the newest frame at most a period before the
  read (the chip measured it before the read, and no later than one period before it),
  otherwise (a chip clock off its nominal period, a reset FIFO) they start again from the
  read time. Stamps never go back, and lie up to a period after the chip's instant (the
  phase of the first read; a chip-clock estimate is issue 25 item 4).
"""

from __future__ import annotations

from dataclasses import dataclass
from itertools import pairwise

from imuhal.bus.registers import RegisterView
from imuhal_chips.mpu9250 import registers as r
from imuhal_chips.mpu9250.decode import decode_counts, temperature_degc

FRAME_BYTES = 14
"""ACCEL_XOUT_H..GYRO_ZOUT_L: accel (6), temperature (2), gyro (6)."""
FIFO_EN_VALUE = r.FIFO_TEMP | r.FIFO_GYRO_X | r.FIFO_GYRO_Y | r.FIFO_GYRO_Z | r.FIFO_ACCEL
OVERFLOW_MARGIN_FRAMES = 3
"""Reset when fewer than this many frames of room are left (Linux inv_mpu_ring.c)."""
TEMPERATURE_JUMP_DEGC = 2.0
"""A larger step of the die temperature between consecutive frames is no measurement."""


@dataclass(frozen=True)
class FifoRead:
    """One read's outcome: frames (14 bytes each, oldest first) with their time stamps, and
    whether the FIFO was reset (an overflow or a corrupt burst: its frames are lost)."""

    frames: list[bytes]
    stamps_ns: list[int]
    reset: bool = False


def frames_consistent(frames: list[bytes]) -> bool:
    """False when the temperature jumps by more than TEMPERATURE_JUMP_DEGC between two
    consecutive frames (a shifted burst)."""
    temps = [temperature_degc(decode_counts(f).temperature) for f in frames]
    return all(abs(b - a) <= TEMPERATURE_JUMP_DEGC for a, b in pairwise(temps))


class FifoReader:
    """Reads whole frames from the FIFO of one MPU-9250 (see the module docstring)."""

    def __init__(self, regs: RegisterView, period_ns: int) -> None:
        self.regs = regs
        self.period_ns = period_ns
        self.overflow_at = r.FIFO_SIZE_BYTES - OVERFLOW_MARGIN_FRAMES * FRAME_BYTES
        self._last_ns: int | None = None
        """The newest frame's stamp of the previous read (None: start from the read time)."""

    def reset(self, user_ctrl: int) -> None:
        """Empty the FIFO (USER_CTRL.FIFO_RST self-clears; the other bits rewritten)."""
        self.regs.write(r.USER_CTRL, user_ctrl | r.USER_FIFO_RST)
        self._last_ns = None

    def _newest_stamp(self, now_ns: int, n: int) -> int:
        last = self._last_ns
        if last is not None:
            continued = last + n * self.period_ns
            if 0 <= now_ns - continued < self.period_ns:
                return continued
            # never back: the first new frame comes after the last one stamped
            return max(now_ns, last + n * self.period_ns - self.period_ns + 1)
        return now_ns

    def read(self, now_ns: int, user_ctrl: int, *, overflowed: bool) -> FifoRead:
        """Count, check for overflow, read whole frames. ``overflowed``: INT_STATUS said
        FIFO_OFLOW_INT."""
        high, low = self.regs.read(r.FIFO_COUNTH, 2)
        count = (high & 0x1F) << 8 | low
        if overflowed or count > self.overflow_at:
            self.reset(user_ctrl)
            return FifoRead([], [], reset=True)
        n = count // FRAME_BYTES
        if not n:
            return FifoRead([], [])
        data = self.regs.read(r.FIFO_R_W, n * FRAME_BYTES)
        frames = [data[i * FRAME_BYTES:(i + 1) * FRAME_BYTES] for i in range(n)]
        if not frames_consistent(frames):
            self.reset(user_ctrl)
            return FifoRead([], [], reset=True)
        newest = self._newest_stamp(now_ns, n)
        self._last_ns = newest
        stamps = [newest - (n - 1 - i) * self.period_ns for i in range(n)]
        return FifoRead(frames, stamps)
