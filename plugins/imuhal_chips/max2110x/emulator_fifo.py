"""The MAX21100's and MAX21105's FIFO, from the chip's side, for their emulators: one model
(:class:`Max2110xFifo`), each part's register map (:class:`FifoMap`).

MAX21105 (user guide rev 1.4, imuhal's chip facts section 5) [DS]: bank 0 FIFO_STORE 0x17
([1] accelerometer, [0] gyro stored), FIFO_THS 0x18 (the threshold in samples, full axis
sets), FIFO_CFG 0x19 ([4:3] mode 00 off, 01 normal, 10 interrupt, 11 snapshot; [2] double
size; [1] interrupt mode; [0] overrun); common bank FIFO_COUNT 0x3C, FIFO_STATUS 0x3D (bit 4
data_lost, bit 3 read_empty, bit 2 ovthold, bit 1 full, bit 0 empty), FIFO_DATA 0x3E (a
burst without increment pops the FIFO); a sample is GX, GY, GZ, AX, AY, AZ big-endian words.
Not in the facts, [UNVERIFIED]: the depth (the MAX21100's 64 words are taken; double size
is taken to double it), FIFO_COUNT's unit (words, as on the MAX21100), what ``overrun``
means (taken: a full FIFO overwrites its oldest frame instead of dropping the new one, and
sets data_lost), which events set and clear the status bits (taken as below); the
interrupt and snapshot modes are not modelled (the FIFO stores nothing in them).

MAX21100 (imuhal's chip facts, section 6, and the sources behind them):
- Addresses [V]: FIFO_TH 0x17 and FIFO_CFG 0x18 in bank 0; FIFO_COUNT 0x3C, FIFO_STATUS
  0x3D, FIFO_DATA 0x3E in the common bank.
- From Kris Winer's MAX21100 sketch (calibrateMAX21100, one of the facts' four sources)
  [SS]: FIFO_CFG 0x41 "FIFO normal mode and accumulate gyro data", 0x42 the same for the
  accelerometer, 0x00 "turn off FIFO"; FIFO_TH is a threshold in words; FIFO_STATUS bit 2
  says the threshold was reached; FIFO_COUNT counts words (three per 3-axis sample); "128
  bytes in the FIFO = 64 words"; FIFO_DATA is read 6 bytes at a time.

What is not known for the MAX21100 and is taken from the MAX21105's user guide or assumed,
each [UNVERIFIED]:
- FIFO_CFG [7:6] the mode, 00 off, 01 normal (Winer's 0x40); 10 interrupt and 11 snapshot
  as on the MAX21105 ([4:3] there) are not modelled: the FIFO stores nothing in them.
  FIFO_CFG [1] accelerometer, [0] gyro stored (Winer; the MAX21105's FIFO_STORE order).
- The MAX21105's frame layout, status bits and popping (above). The MAX21105's FIFO_CFG [0]
  "overrun" choice has no known MAX21100 bit (Winer's bit 0 stores the gyro), so its
  oldest frames are never overwritten.

Both parts, as modelled:
- A frame is the stored channels' words, gyro X, Y, Z then accel X, Y, Z, big-endian,
  written at each measurement of the faster stored channel (the gyro on a tie) with the
  other's latest words, once both are latched for that instant.
- Full (normal mode, no overrun): a frame that does not fit whole is not written;
  FIFO_STATUS data_lost is set.
- FIFO_STATUS: read_empty is FIFO_DATA read while the FIFO is on and empty (the read
  returns 0x00); ovthold is a count at or over the threshold (not 0); full is no room for
  another frame; empty. Reading FIFO_STATUS clears data_lost and read_empty.
- FIFO_DATA pops one byte per byte read; a burst with the no-increment bit pops one byte
  per byte; with increment the pointer moves on to 0x3F after the first.
- Writing the mode off empties the FIFO (how the driver resets it: off, then its
  configuration again); a soft reset empties it too.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Final

STATUS_DATA_LOST: Final = 0x10
STATUS_READ_EMPTY: Final = 0x08
STATUS_OVTHOLD: Final = 0x04
STATUS_FULL: Final = 0x02
STATUS_EMPTY: Final = 0x01
EMPTY_READ: Final = 0x00
"""What FIFO_DATA reads with nothing in the FIFO [UNVERIFIED]."""


@dataclass(frozen=True)
class FifoMap:
    """Where a part keeps its FIFO's settings (bank 0) and what their bits mean."""

    part: str
    cfg: int
    """FIFO_CFG's address."""
    threshold: int
    """The threshold register's address."""
    store: int | None
    """FIFO_STORE's address; None: the store bits are in FIFO_CFG."""
    mode_mask: int
    mode_normal: int
    store_gyro: int
    store_accel: int
    overrun: int
    """FIFO_CFG's bit for "a full FIFO overwrites its oldest frame" (0: the part has none)."""
    double_size: int
    """FIFO_CFG's bit that doubles the depth (0: none)."""
    depth_words: int
    threshold_unit_words: int
    """Words per unit of the threshold register."""

    @property
    def registers(self) -> frozenset[int]:
        return frozenset(r for r in (self.cfg, self.threshold, self.store) if r is not None)


MAX21100_FIFO: Final = FifoMap(
    part="MAX21100", cfg=0x18, threshold=0x17, store=None, mode_mask=0xC0, mode_normal=0x40,
    store_gyro=0x01, store_accel=0x02, overrun=0, double_size=0,
    depth_words=64,  # 128 bytes (Winer's comment) [UNVERIFIED: no datasheet found]
    threshold_unit_words=1)
MAX21105_FIFO: Final = FifoMap(
    part="MAX21105", cfg=0x19, threshold=0x18, store=0x17, mode_mask=0x18, mode_normal=0x08,
    store_gyro=0x01, store_accel=0x02, overrun=0x01, double_size=0x04,
    depth_words=64,  # [UNVERIFIED]: the MAX21100's
    threshold_unit_words=3)  # samples, a full axis set each [DS]


class Max2110xFifo:
    """One part's FIFO: its bytes and status (module docstring), its settings where
    ``fifo_map`` says."""

    def __init__(self, fifo_map: FifoMap) -> None:
        self.map = fifo_map
        self._bytes = bytearray()
        """The stored bytes, oldest first (at most the depth: 128 or 256 bytes)."""
        self.threshold_words = 0
        self.cfg = 0
        self.store = 0
        """FIFO_STORE (MAX21105; the MAX21100's store bits are in ``cfg``)."""
        self._sticky = 0
        """data_lost and read_empty: set by events, cleared by a FIFO_STATUS read."""
        self.frames_dropped = 0
        """Frames not written because they did not fit (since construction)."""
        self.frames_written = 0

    def write(self, reg: int, value: int) -> None:
        """One of the FIFO's settings written (``map.registers``); FIFO_CFG with the mode
        off empties the FIFO."""
        m = self.map
        if reg == m.threshold:
            self.threshold_words = value * m.threshold_unit_words
        elif reg == m.store:
            self.store = value
        elif reg == m.cfg:
            self.cfg = value
            if not value & m.mode_mask:
                self.clear()

    @property
    def depth_words(self) -> int:
        return self.map.depth_words * (2 if self.cfg & self.map.double_size else 1)

    def clear(self) -> None:
        self._bytes.clear()
        self._sticky = 0

    @property
    def storing(self) -> tuple[bool, bool]:
        """(gyro, accelerometer) stored: normal mode with the channel's store bit."""
        m = self.map
        if self.cfg & m.mode_mask != m.mode_normal:
            return False, False
        bits = self.cfg if m.store is None else self.store
        return bool(bits & m.store_gyro), bool(bits & m.store_accel)

    def words(self) -> int:
        return len(self._bytes) // 2

    def push(self, frame: bytes) -> None:
        """One frame's bytes (whole words). When it does not fit whole: not written, or, with
        the overrun bit, written over the oldest frame; either sets data_lost."""
        if len(self._bytes) + len(frame) > 2 * self.depth_words:
            self.frames_dropped += 1
            self._sticky |= STATUS_DATA_LOST
            if not self.cfg & self.map.overrun:
                return
            del self._bytes[:len(frame)]
        self._bytes.extend(frame)
        self.frames_written += 1

    def push_frames(self, frames: bytes, frame_len: int) -> None:
        """:meth:`push` of each ``frame_len`` bytes of ``frames`` in turn, at once: the
        frames that fit written, the rest dropped (each counted, data_lost set); a FIFO
        that overwrites its oldest frames takes them one by one."""
        if self.cfg & self.map.overrun:
            for k in range(0, len(frames), frame_len):
                self.push(frames[k:k + frame_len])
            return
        count = len(frames) // frame_len
        room = max(0, (2 * self.depth_words - len(self._bytes)) // frame_len)
        fitting = min(count, room)
        self._bytes += frames[:fitting * frame_len]
        self.frames_written += fitting
        if fitting < count:
            self.frames_dropped += count - fitting
            self._sticky |= STATUS_DATA_LOST

    def pop(self) -> int:
        if not self._bytes:
            if self.cfg & self.map.mode_mask:  # a FIFO turned off has no read to flag
                self._sticky |= STATUS_READ_EMPTY
            return EMPTY_READ
        value = self._bytes[0]
        del self._bytes[0]
        return value

    def pop_many(self, count: int) -> bytes:
        """``count`` bytes popped one after another (:meth:`pop` each): what the FIFO
        holds, then the empty read's byte for each beyond it."""
        stored = self._bytes
        taken = bytes(stored[:count])
        del stored[:count]
        if len(taken) < count:
            return taken + bytes((self.pop(),)) * (count - len(taken))
        return taken

    def status(self, frame_words: int) -> int:
        """FIFO_STATUS as read now; the read clears data_lost and read_empty."""
        n = self.words()
        value = self._sticky
        if self.threshold_words and n >= self.threshold_words:
            value |= STATUS_OVTHOLD
        if frame_words and n + frame_words > self.depth_words:
            value |= STATUS_FULL
        if not self._bytes:
            value |= STATUS_EMPTY
        self._sticky = 0
        return value
