"""Reading the MAX21100's or MAX21105's FIFO (``read: fifo``): whole frames, overflow as a
counted loss and a reset, a check for a shifted FIFO, frames stamped on the chip's own clock
or with its data-ready edges (imuhal.drivers.fifo_frames, shared with the MPU-9250's reader).

The MAX21105's FIFO is the documented one (its user guide, rev 1.4, imuhal's chip facts
section 5) [DS]: FIFO_STORE 0x17, FIFO_THS 0x18 (in samples), FIFO_CFG 0x19 (mode [4:3],
overrun [0]: left clear, so a full FIFO writes no more), FIFO_COUNT 0x3C, FIFO_STATUS 0x3D
(bit 4 data_lost), FIFO_DATA 0x3E popped by a burst without increment, frames of gyro X,
Y, Z then accel X, Y, Z big-endian words. Its depth is not in the facts: the MAX21100's 64
words are taken (single size) [UNVERIFIED], as is FIFO_COUNT in words. Where each part keeps
its settings: registers.MAX21100_FIFO, registers.MAX21105_FIFO.

No MAX21100 datasheet is known (imuhal's chip facts, section 6). The FIFO's addresses are
certain (FIFO_TH 0x17, FIFO_CFG 0x18, FIFO_COUNT 0x3C, FIFO_STATUS 0x3D, FIFO_DATA 0x3E);
Kris Winer's MAX21100 sketch, one of the facts' sources, uses it (FIFO_CFG 0x41/0x42 "normal
mode" with gyro or accelerometer data, FIFO_COUNT in words, "128 bytes = 64 words",
FIFO_STATUS bit 2 for the threshold). Everything else is the MAX21105's user guide or an
assumption, and this reader relies on it, each [UNVERIFIED]:

- FIFO_CFG [7:6] 01 normal mode, [1] accelerometer and [0] gyro stored; 00 turns the FIFO
  off and empties it (the reset: off, then the configuration again).
- A frame is gyro X, Y, Z then accel X, Y, Z, big-endian words (the MAX21105's layout), one
  per measurement of both (``read: fifo`` needs equal gyro and accelerometer rates), so the
  64-word FIFO holds 10 frames: 40 ms at 250 Hz.
- A full FIFO in normal mode writes no further frame and sets FIFO_STATUS bit 4 data_lost
  (the MAX21105's bit; its FIFO_CFG [0] "overrun" choice has no known MAX21100 bit).
- FIFO_DATA read with the no-increment bit (bit 6 of the address byte) pops one byte per
  byte read, as on the MAX21105.

How it reads (as the MPU-9250's reader and PX4/Linux do, adapted to a 10-frame FIFO):

- **Count and status in one transaction** (FIFO_COUNT, FIFO_STATUS), then ``count //
  6`` whole frames in one burst from FIFO_DATA. Frames the chip appends between the count
  and the burst stay for the next read (the count-to-read race costs nothing: the burst
  never reads past the count). A FIFO that stops when full does not wrap, so no room is
  kept free: a full FIFO without data_lost holds every frame since the last read, and with
  10 frames a margin would cost a fifth of the depth. Were the assumption wrong (a FIFO
  that overwrites its oldest words), the shifted-frame check below catches the wrap.
- **Overflow**: data_lost set means frames were not written after the FIFO filled: the
  frames it kept (the oldest since the last read, in order) are read and handed out,
  placed by the data-ready edges or the chip's clock learned so far (lost with the FIFO
  when neither places them to 1 % of a period), and the FIFO is reset, so the frames
  counted from then on are the chip's again; the overflow is counted in the driver's
  ``health.fifo_overflows`` and the frames not written are lost (the pipeline's ledger
  charges them to ``fifo_overflow``). This keeps every frame the chip's buffering kept.
- **Shifted FIFO** (no die temperature is in a frame, so ArduPilot's temperature test does
  not apply): the chip writes whole frames, so a count that is not a whole number of frames
  means a burst popped part of a frame (a transfer cut short) and every frame after it is
  misaligned; a word beyond the +-30000 counts the chip clips at is no measurement either
  (a byte out of place). Either resets the FIFO and drops the burst, counted as above.
- **Time stamps**: as the MPU-9250's (imuhal.drivers.fifo_frames).
"""

from __future__ import annotations

import numpy as np

from imuhal.bus.registers import RegisterView
from imuhal.core.clock import Clock
from imuhal.drivers.fifo_frames import FifoFrames, FifoRead
from imuhal_chips.max2110x.registers import (
    FIFO_DEPTH_WORDS,
    FIFO_FRAME_WORDS,
    FIFO_STATUS_DATA_LOST,
    FULL_SCALE_COUNTS,
    NO_INCREMENT_BIT,
    FifoRegisters,
    Reg,
)

FRAME_BYTES = 2 * FIFO_FRAME_WORDS
DEPTH_FRAMES = FIFO_DEPTH_WORDS // FIFO_FRAME_WORDS
"""Whole frames the FIFO holds: 10."""


def frames_aligned(count_words: int, frames: list[bytes]) -> bool:
    """False when the FIFO is shifted: a count that is not whole frames, or a word beyond
    the chip's +-30000 counts."""
    if count_words % FIFO_FRAME_WORDS:
        return False
    return _words_in_range(b"".join(frames))


def _words_in_range(data: bytes) -> bool:
    """Every big-endian word of ``data`` within the chip's +-30000 counts: one look at
    the whole burst (a word at a time in Python cost more than the rest of the read)."""
    if not data:
        return True
    words = np.frombuffer(data, dtype=">i2")
    return bool(_MIN(words) >= -FULL_SCALE_COUNTS) and bool(_MAX(words) <= FULL_SCALE_COUNTS)


_MIN = np.minimum.reduce
_MAX = np.maximum.reduce
"""The ufuncs' reductions called directly (``ndarray.min`` goes through a Python wrapper)."""


class FifoReader(FifoFrames):
    """Reads whole frames from the FIFO of one MAX21100 or MAX21105 (the module docstring);
    ``fifo``: where the part keeps its FIFO's settings."""

    def __init__(self, regs: RegisterView, period_ns: int, clock: Clock,
                 fifo: FifoRegisters) -> None:
        super().__init__(period_ns, clock)
        self.regs = regs
        self.fifo = fifo
        self.frame_bytes = FRAME_BYTES
        self._count_frame = bytes((regs.read_address(Reg.FIFO_COUNT, 2),))
        # FIFO_DATA in one burst without increment (bit 6 on SPI and I2C alike)
        self._data_frame = bytes((regs.read_address(Reg.FIFO_DATA, 1) | NO_INCREMENT_BIT,))

    @property
    def depth_frames(self) -> int:
        return DEPTH_FRAMES

    def reset(self, *, restart: bool = True, same_oscillator: bool = False) -> None:
        """Empty the FIFO: its mode off, then the configuration again. ``restart``: the
        chip's sampling restarted too (configured), not only its FIFO; ``same_oscillator``:
        at the period it had (FifoFrames.cleared)."""
        requested_ns = self.clock.now_ns()
        self.regs.write(self.fifo.cfg, 0x00)
        self.regs.write(self.fifo.cfg, self.fifo.cfg_on)
        self.cleared(requested_ns, restart=restart, same_oscillator=same_oscillator)

    def read(self) -> FifoRead:
        """Count and status, check for overflow, read whole frames, check alignment."""
        lo_ns = self.clock.now_ns()
        count, status = self.regs.send(self._count_frame, 2)
        hi_ns = self.clock.now_ns()
        if count > FIFO_DEPTH_WORDS:
            return self._drop([])
        n = count // FIFO_FRAME_WORDS
        frames: list[bytes] = []
        if n:
            data = self.regs.send(self._data_frame, n * FRAME_BYTES)
            # frames_aligned on the burst as read: a word beyond the chip's counts
            if not _words_in_range(data):
                return self._drop([])
            frames = [data[i * FRAME_BYTES:(i + 1) * FRAME_BYTES] for i in range(n)]
        if count % FIFO_FRAME_WORDS:  # not whole frames (frames_aligned): shifted
            return self._drop([])
        if status & FIFO_STATUS_DATA_LOST:
            return self._drop(frames)  # what it kept is good; what came after, lost
        return self.took(frames, lo_ns, hi_ns)

    def _drop(self, kept: list[bytes]) -> FifoRead:
        """An overflow (``kept``: the frames the full FIFO kept) or a shifted FIFO (none):
        the FIFO is reset (FifoFrames.dropped)."""
        out = self.dropped(kept)
        self.reset(restart=False)
        return out
