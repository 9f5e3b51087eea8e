"""In-driver validity checks every driver shares: a sample is valid only when it is
physically plausible for its chip.

- ``blank_flag``: a frame of all 0x00 or all 0xFF bytes is what an undriven bus returns (an
  unpowered or missing chip, MISO or SDA stuck), never a measurement -> ``BLANK``.
- ``FrozenWatch``: a converting chip's noise never repeats the same raw frame for long;
  ``n`` identical frames in a row -> ``FROZEN`` (a hung conversion still reporting its old
  result). Each driver derives ``n`` from its chip's noise at its quietest setting.
- ``range_flag``: a decoded value outside the limits the chip can report -> ``OUT_OF_RANGE``.

Samples flagged STALE, BLANK or FROZEN carry NaN values (``NAN3``): they are not
measurements. Samples flagged SATURATED, OVERFLOW or OUT_OF_RANGE keep the value read, so
a log shows what the chip said.
"""

from __future__ import annotations

import math
from collections.abc import Hashable, Iterable

from imuhal.core.samples import SampleFlag

NAN3 = (math.nan, math.nan, math.nan)
"""The value of a vector sample that is not a measurement (stale, blank, frozen)."""


def blank_flag(frame: bytes) -> SampleFlag:
    """``BLANK`` when every byte of ``frame`` is 0x00 or every byte is 0xFF, else ``OK``."""
    if frame and (frame.count(0xFF) == len(frame) or frame.count(0x00) == len(frame)):
        return SampleFlag.BLANK
    return SampleFlag.OK


def range_flag(values: Iterable[float], low: float, high: float) -> SampleFlag:
    """``OUT_OF_RANGE`` when any finite value lies outside ``[low, high]``, else ``OK``."""
    if any(math.isfinite(v) and not low <= v <= high for v in values):
        return SampleFlag.OUT_OF_RANGE
    return SampleFlag.OK


class FrozenWatch:
    """Counts identical raw frames in a row, per channel.

    ``observe`` is called with each frame the chip presents as a *new* measurement; it
    returns ``FROZEN`` from the ``n``-th identical frame in a row on, until the frame changes.
    The history survives a restart of the chip: a chip still repeating the frame after a
    reset is still frozen, and a working one changes its frame with its first measurement.
    ``n`` must make a real sensor's repeat improbable: with per-axis noise of sigma LSB,
    two frames of ``a`` axes match with probability about ``(1 / (2 sqrt(pi) sigma))**a``.
    """

    def __init__(self, n: int) -> None:
        if n < 2:
            raise ValueError(f"a frozen frame needs at least 2 repeats, got {n}")
        self.n = n
        self._last: dict[Hashable, bytes] = {}
        self._repeats: dict[Hashable, int] = {}

    def observe(self, key: Hashable, frame: bytes) -> SampleFlag:
        if self._last.get(key) == frame:
            self._repeats[key] += 1
        else:
            self._last[key] = bytes(frame)
            self._repeats[key] = 1
        return SampleFlag.FROZEN if self._repeats[key] >= self.n else SampleFlag.OK
