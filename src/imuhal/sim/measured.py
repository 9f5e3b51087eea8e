"""The instants at which an emulated chip completed a measurement, kept as runs.

An emulator records every measurement of the stream its driver accounts for, so a test (and
the fault matrix's frame ledger check) can count exactly what the chip produced between two
samples (``ChipEmulator.frames_between``). Kept as one 8-byte integer per measurement, that
record grew with the run: about 2.8 MB per 1,000 simulated s on the seed GPS vario (200 +
100 + 50 measurements a second), the soak's unexplained RSS growth (issue 26). A chip
measures on its own clock at a fixed period, so its instants are arithmetic progressions
broken only where its schedule restarts (a reset, a reconfiguration, a skipped slot): kept
as (first instant, period, count) runs, the record holds one run per break, not one number
per measurement, and answers every question the array did, exactly.
"""

from __future__ import annotations

from array import array
from bisect import bisect_right
from collections.abc import Iterator
from typing import Any, overload

import numpy as np


class MeasuredInstants:
    """Ascending instants (ns) as runs of equal steps; reads like the sequence of them
    (``len``, indexing, slicing, iteration, ``numpy.asarray``)."""

    def __init__(self) -> None:
        self._firsts = array("q")
        self._steps = array("q")
        self._ends = array("q")
        """Measurements up to and including each run (cumulative counts)."""

    @property
    def runs(self) -> int:
        """Runs held: what the record's size grows with (one per break of the cadence)."""
        return len(self._firsts)

    def add(self, first_ns: int, period_ns: int, count: int) -> None:
        """``count`` measurements at ``first_ns``, ``first_ns + period_ns``, ... (never
        before the last one recorded)."""
        if count <= 0:
            return
        firsts = self._firsts
        if firsts:
            ends, steps = self._ends, self._steps
            # the last instant recorded (``self[-1]``, worked out from the last run: an
            # emulator adds about 500 times per simulated second)
            in_run = ends[-1] - (ends[-2] if len(ends) > 1 else 0)
            last_ns = firsts[-1] + (in_run - 1) * steps[-1]
            step = first_ns - last_ns
            if step < 0:
                raise ValueError(f"measurement at {first_ns} ns before the last one, "
                                 f"{last_ns} ns")
            if step > 0 and (in_run == 1 or step == steps[-1]) \
                    and (count == 1 or period_ns == step):
                steps[-1] = step
                ends[-1] += count
                return
        self._firsts.append(first_ns)
        self._steps.append(period_ns if count > 1 else 0)
        self._ends.append((self._ends[-1] if self._ends else 0) + count)

    def count_until(self, t_ns: int) -> int:
        """How many instants are at or before ``t_ns`` (``bisect_right`` on the sequence)."""
        run = bisect_right(self._firsts, t_ns) - 1
        if run < 0:
            return 0
        before = self._ends[run - 1] if run else 0
        count = self._ends[run] - before
        step = self._steps[run]
        if step > 0:
            count = min(count, (t_ns - self._firsts[run]) // step + 1)
        return before + count

    def __len__(self) -> int:
        return self._ends[-1] if self._ends else 0

    @overload
    def __getitem__(self, index: int) -> int: ...

    @overload
    def __getitem__(self, index: slice) -> list[int]: ...

    def __getitem__(self, index: int | slice) -> int | list[int]:
        if isinstance(index, slice):
            return [self[i] for i in range(*index.indices(len(self)))]
        n = len(self)
        if index < 0:
            index += n
        if not 0 <= index < n:
            raise IndexError("measurement index out of range")
        run = bisect_right(self._ends, index)
        offset = index - (self._ends[run - 1] if run else 0)
        return self._firsts[run] + offset * self._steps[run]

    def __iter__(self) -> Iterator[int]:
        start = 0
        for first, step, end in zip(self._firsts, self._steps, self._ends, strict=True):
            for k in range(end - start):
                yield first + k * step
            start = end

    def __array__(self, dtype: Any = None, copy: Any = None) -> np.ndarray:
        out = np.fromiter(self, dtype=np.int64, count=len(self))
        return out if dtype is None else out.astype(dtype)
