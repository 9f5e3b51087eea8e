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
  are held back (at most ``fifo_frames.HOLD_MAX_FRAMES``, kept in the driver, so nothing
  is lost) and handed out stamped once it does.
- **Time stamps from data-ready edges** (a profile's ``interrupt:`` line on the chip's INT
  pin, RAW_RDY_EN: one edge per sample; imuhal.drivers.edge_stamps): each frame is stamped
  with its own edge's kernel time stamp, as Linux's inv_sensors_timestamp.c stamps FIFO
  frames from interrupt times, however many edges go to one read; the read-time estimate
  above is not needed then. Frames whose edge has not come yet wait in the reader (at most
  ``fifo_frames.EDGE_WAIT_FRAMES``; more means the line went silent: they go on one learned period
  after the previous stamp). ``drain()`` hands out what is held when a run ends.

The stamping and hand-out are shared with every FIFO reader (imuhal.drivers.fifo_frames);
this module does the MPU-9250's register work.
"""

from __future__ import annotations

import struct
from itertools import pairwise

from imuhal.bus.registers import RegisterView
from imuhal.core.clock import Clock
from imuhal.drivers.fifo_frames import FifoFrames, FifoRead
from imuhal_chips.mpu9250 import registers as r
from imuhal_chips.mpu9250.decode import temperature_degc

FRAME_BYTES = 14
_TEMPERATURE_WORD = struct.Struct(">h").unpack_from
"""ACCEL_XOUT_H..GYRO_ZOUT_L: accel (6), temperature (2), gyro (6); a slave's bytes follow."""
FIFO_EN_VALUE = r.FIFO_TEMP | r.FIFO_GYRO_X | r.FIFO_GYRO_Y | r.FIFO_GYRO_Z | r.FIFO_ACCEL
OVERFLOW_MARGIN_FRAMES = 2
"""Reset when fewer than this many frames of room are left (Linux inv_mpu_ring.c keeps 3
of its frames; with the AK8963's bytes the FIFO holds only 23, so imuhal keeps 2: a count
read with two frames of room cannot have wrapped, and the burst reads no further than the
count)."""
TEMPERATURE_JUMP_DEGC = 2.0
"""A larger step of the die temperature between consecutive frames is no measurement."""


def frames_consistent(frames: list[bytes]) -> bool:
    """False when the temperature jumps by more than TEMPERATURE_JUMP_DEGC between two
    consecutive frames (a shifted burst)."""
    # the temperature word alone (bytes 6-7 of a frame), decoded as decode_counts does
    temps = [temperature_degc(_TEMPERATURE_WORD(f, 6)[0]) for f in frames]
    return all(abs(b - a) <= TEMPERATURE_JUMP_DEGC for a, b in pairwise(temps))


class FifoReader(FifoFrames):
    """Reads whole frames from the FIFO of one MPU-9250 (see the module docstring); the
    stamping and hand-out are imuhal.drivers.fifo_frames'. ``slave_bytes``: slave 0's LENG
    when its bytes are in the FIFO (FIFO_EN.SLV0)."""

    def __init__(self, regs: RegisterView, period_ns: int, clock: Clock, *,
                 slave_bytes: int = 0) -> None:
        super().__init__(period_ns, clock)
        self.regs = regs
        self.frame_bytes = FRAME_BYTES + slave_bytes
        self.overflow_at = r.FIFO_SIZE_BYTES - OVERFLOW_MARGIN_FRAMES * self.frame_bytes

    @property
    def depth_frames(self) -> int:
        """Whole frames the FIFO holds."""
        return r.FIFO_SIZE_BYTES // self.frame_bytes

    def reset(self, user_ctrl: int, *, restart: bool = True,
              same_oscillator: bool = False) -> None:
        """Empty the FIFO (USER_CTRL.FIFO_RST self-clears; the other bits rewritten).
        ``restart``: the chip's sampling restarted too (configured), not only its FIFO;
        ``same_oscillator``: at the period it had (FifoFrames.cleared)."""
        requested_ns = self.clock.now_ns()
        self.regs.write(r.USER_CTRL, user_ctrl | r.USER_FIFO_RST)
        self.cleared(requested_ns, restart=restart, same_oscillator=same_oscillator)

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
        return self.took(frames, lo_ns, hi_ns)

    def _drop(self, user_ctrl: int) -> FifoRead:
        """An overflow or a corrupt burst: the FIFO is reset unread (FifoFrames.dropped)."""
        out = self.dropped()
        self.reset(user_ctrl, restart=False)
        return out
