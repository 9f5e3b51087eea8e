"""The MAX21100's FIFO, from the chip's side, for its emulator.

What is known (imuhal's chip facts, section 6, and the sources behind them):
- Addresses [V]: FIFO_TH 0x17 and FIFO_CFG 0x18 in bank 0; FIFO_COUNT 0x3C, FIFO_STATUS
  0x3D, FIFO_DATA 0x3E in the common bank.
- From Kris Winer's MAX21100 sketch (calibrateMAX21100, one of the facts' four sources)
  [SS]: FIFO_CFG 0x41 "FIFO normal mode and accumulate gyro data", 0x42 the same for the
  accelerometer, 0x00 "turn off FIFO"; FIFO_TH is a threshold in words; FIFO_STATUS bit 2
  says the threshold was reached; FIFO_COUNT counts words (three per 3-axis sample); "128
  bytes in the FIFO = 64 words"; FIFO_DATA is read 6 bytes at a time.

What is not known for the MAX21100 and is taken from the MAX21105's user guide (rev 1.4,
facts section 5) or assumed, each [UNVERIFIED]:
- FIFO_CFG [7:6] the mode, 00 off, 01 normal (Winer's 0x40); 10 interrupt and 11 snapshot
  as on the MAX21105 ([4:3] there) are not modelled: the FIFO stores nothing in them.
  FIFO_CFG [1] accelerometer, [0] gyro stored (Winer; the MAX21105's FIFO_STORE order).
- A frame is the stored channels' words, gyro X, Y, Z then accel X, Y, Z, big-endian (the
  MAX21105's layout), written at each measurement of the faster stored channel (the gyro on
  a tie) with the other's latest words, once both are latched for that instant.
- Depth 64 words (Winer's comment): 10 whole gyro + accel frames.
- Full (normal mode): a frame that does not fit whole is not written; FIFO_STATUS data_lost
  (bit 4) is set. The MAX21105's FIFO_CFG [0] "overrun" choice has no known MAX21100 bit
  (Winer's bit 0 stores the gyro), so the oldest frames are never overwritten.
- FIFO_STATUS as on the MAX21105: bit 4 data_lost, bit 3 read_empty (FIFO_DATA read while
  the FIFO is on and empty; the read returns 0x00), bit 2 ovthold (count >= FIFO_TH,
  FIFO_TH not 0), bit 1 full (no room for another frame), bit 0 empty. Reading FIFO_STATUS
  clears data_lost and read_empty.
- FIFO_DATA pops one byte per byte read; a burst with the no-increment bit (the MAX21105's
  "burst without increment pops FIFO") pops one byte per byte; with increment the pointer
  moves on to 0x3F after the first.
- Writing FIFO_CFG with the mode off empties the FIFO (how the driver resets it: off, then
  its configuration again); a soft reset empties it too.
"""

from __future__ import annotations

from collections import deque
from typing import Final

DEPTH_WORDS: Final = 64
"""128 bytes (Winer's comment) [UNVERIFIED for the MAX21100's datasheet, none found]."""
MODE_SHIFT: Final = 6
MODE_MASK: Final = 0xC0
MODE_NORMAL: Final = 0x40
STORE_GYRO: Final = 0x01
STORE_ACCEL: Final = 0x02
STATUS_DATA_LOST: Final = 0x10
STATUS_READ_EMPTY: Final = 0x08
STATUS_OVTHOLD: Final = 0x04
STATUS_FULL: Final = 0x02
STATUS_EMPTY: Final = 0x01
EMPTY_READ: Final = 0x00
"""What FIFO_DATA reads with nothing in the FIFO [UNVERIFIED]."""


class Max21100Fifo:
    """The FIFO's bytes and status (module docstring)."""

    def __init__(self) -> None:
        self._bytes: deque[int] = deque()
        self.threshold_words = 0
        self.cfg = 0
        self._sticky = 0
        """data_lost and read_empty: set by events, cleared by a FIFO_STATUS read."""
        self.frames_dropped = 0
        """Frames not written because they did not fit (since construction)."""
        self.frames_written = 0

    def configure(self, cfg: int) -> None:
        """FIFO_CFG written: the mode off empties the FIFO."""
        self.cfg = cfg
        if not cfg & MODE_MASK:
            self.clear()

    def clear(self) -> None:
        self._bytes.clear()
        self._sticky = 0

    @property
    def storing(self) -> tuple[bool, bool]:
        """(gyro, accelerometer) stored: normal mode with the channel's store bit."""
        if self.cfg & MODE_MASK != MODE_NORMAL:
            return False, False
        return bool(self.cfg & STORE_GYRO), bool(self.cfg & STORE_ACCEL)

    def words(self) -> int:
        return len(self._bytes) // 2

    def push(self, frame: bytes) -> None:
        """One frame's bytes (whole words); not written when it does not fit whole."""
        if len(self._bytes) + len(frame) > 2 * DEPTH_WORDS:
            self.frames_dropped += 1
            self._sticky |= STATUS_DATA_LOST
            return
        self._bytes.extend(frame)
        self.frames_written += 1

    def pop(self) -> int:
        if not self._bytes:
            if self.cfg & MODE_MASK:  # a FIFO turned off has no read to flag
                self._sticky |= STATUS_READ_EMPTY
            return EMPTY_READ
        return self._bytes.popleft()

    def status(self, frame_words: int) -> int:
        """FIFO_STATUS as read now; the read clears data_lost and read_empty."""
        n = self.words()
        value = self._sticky
        if self.threshold_words and n >= self.threshold_words:
            value |= STATUS_OVTHOLD
        if frame_words and n + frame_words > DEPTH_WORDS:
            value |= STATUS_FULL
        if not self._bytes:
            value |= STATUS_EMPTY
        self._sticky = 0
        return value
