"""In-driver validity checks every driver shares: a sample is valid only when it is
physically plausible for its chip.

- ``blank_flag``: a frame of all 0x00 or all 0xFF bytes is what an undriven bus returns (an
  unpowered or missing chip, MISO or SDA stuck), never a measurement -> ``BLANK``.
- ``FrozenWatch``: a converting chip's noise never repeats the same raw frame for long;
  ``n`` identical frames in a row -> ``FROZEN`` (a hung conversion still reporting its old
  result). Each driver derives ``n`` from its chip's noise at its quietest setting;
  ``LearnedFrozenWatch`` shortens it to the repeat odds the chip shows at start-up.
- ``range_flag``: a decoded value outside the limits the chip can report -> ``OUT_OF_RANGE``.
- ``FilterMemory``: a chip that filters its outputs itself (an IIR filter, a moving
  average) carries a wrong measurement into the outputs after it, which can come back in
  range; those outputs -> ``FILTER_SETTLING``. Each driver derives how many outputs its
  chip's settings can carry it (``iir_memory_outputs``). ``LowPassWatch`` is the same for
  an IMU's first-order digital low-pass: it also undoes the filter to see an input at the
  rail that the output hides, and holds the outputs until what such an input can still add
  is below what a valid reading of the chip may be off anyway (its specified offset;
  ``lowpass_settling_outputs``).
- ``StepWatch``: a quantity the physics bounds in how fast it can change (pressure: by the
  fastest vertical speed) that moves further from the last valid value than that bound and
  the chip's noise allow -> ``IMPLAUSIBLE``; a new level that the next readings confirm is
  taken as real (``NewLevel``, which the GNSS driver's epoch checks share).

Samples flagged STALE, BLANK or FROZEN carry NaN values (``NAN3``): they are not
measurements. Samples flagged SATURATED, OVERFLOW or OUT_OF_RANGE keep the value read, so
a log shows what the chip said.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Hashable, Iterable, Mapping, Sequence
from typing import Any, Generic, TypeVar

import numpy as np
import numpy.typing as npt

from imuhal.core.samples import SampleFlag

NAN3 = (math.nan, math.nan, math.nan)
"""The value of a vector sample that is not a measurement (stale, blank, frozen)."""


def blank_flag(frame: bytes) -> SampleFlag:
    """``BLANK`` when every byte of ``frame`` is 0x00 or every byte is 0xFF, else ``OK``."""
    if not frame:
        return SampleFlag.OK
    first = frame[0]  # every reading is looked at: most are told apart by their first byte
    if (first == 0xFF or first == 0x00) and frame.count(first) == len(frame):
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

    def _after(self, key: Hashable, frames: Iterable[bytes]
               ) -> tuple[bool, bytes | None, int]:
        """Whether ``observe`` of ``frames`` in turn would return ``FROZEN`` for one of them,
        and the last frame and its repeat count after them (nothing is observed)."""
        last = self._last.get(key)
        repeats = self._repeats.get(key, 0)
        for frame in frames:
            if frame == last:
                repeats += 1
            else:
                last, repeats = frame, 1
            if repeats >= self.n:
                return True, last, repeats
        return False, last, repeats

    def would_flag(self, key: Hashable, frames: Iterable[bytes]) -> bool:
        """True when ``observe`` of ``frames`` in turn would return ``FROZEN`` for one of
        them; nothing is observed (a driver decoding a burst at once asks first)."""
        return self._after(key, frames)[0]

    def observe_all(self, key: Hashable, frames: Sequence[bytes]) -> bool:
        """``observe`` of each of ``frames`` in turn when none of them would be ``FROZEN``
        (True), else nothing observed (False, as ``would_flag`` says): one pass over a
        burst a driver decodes at once."""
        flagged, last, repeats = self._after(key, frames)
        if flagged:
            return False
        if last is not None:
            self._last[key] = bytes(last)
            self._repeats[key] = repeats
        return True


class LearnedFrozenWatch(FrozenWatch):
    """A ``FrozenWatch`` whose window follows the repeat odds the chip itself shows.

    How often a working chip repeats its frame depends on its noise against its LSB, which
    the datasheet gives only as a typical figure per setting: a quieter part (or an on-chip
    filter smoothing more than the table says) repeats more often, and a window sized from
    the datasheet would flag it ``FROZEN``. So the watch starts with the fixed ``ceiling``
    and counts, over the first ``learn_pairs`` consecutive frames of each key, how many are
    repeats (``k`` of ``m``). The window then becomes the shortest ``n`` whose run of
    ``n - 1`` repeats is no likelier than ``false_alarm``, at the Wilson score upper bound
    of the repeat probability (``z`` = 2, about 98 % one-sided), never longer than
    ``ceiling``. A chip that hangs while the watch learns shows a repeat probability near 1
    and keeps the ceiling, as does a chip quieter than one LSB; the window never grows past
    the fixed one it replaces. Runs of repeats in an AR(1)-filtered output are anti-
    correlated (a repeat leaves the filter where the new measurement was, so the next
    output moves by a full difference), so odds learned pair by pair are not optimistic."""

    WILSON_Z = 2.0

    def __init__(self, ceiling: int, *, learn_pairs: int, false_alarm: float) -> None:
        super().__init__(ceiling)
        if learn_pairs < 1 or not 0.0 < false_alarm < 1.0:
            raise ValueError("learning needs at least one pair and a false-alarm chance "
                             f"in (0, 1), got {learn_pairs} and {false_alarm}")
        self.ceiling = ceiling
        self.learn_pairs = learn_pairs
        self.false_alarm = false_alarm
        self._seen: dict[Hashable, tuple[int, int]] = {}
        """Per key: (pairs compared, repeats among them) while learning."""
        self.windows: dict[Hashable, int] = {}
        """Per key: the learned window, once ``learn_pairs`` pairs were seen."""

    def window(self, key: Hashable) -> int:
        """The window in force for ``key``: learned, or the ceiling while learning."""
        return self.windows.get(key, self.ceiling)

    def observe(self, key: Hashable, frame: bytes) -> SampleFlag:
        if key not in self.windows and key in self._last:
            pairs, repeats = self._seen.get(key, (0, 0))
            pairs, repeats = pairs + 1, repeats + (self._last[key] == frame)
            self._seen[key] = (pairs, repeats)
            if pairs >= self.learn_pairs:
                self.windows[key] = self.window_for(repeats, pairs)
        self.n = self.window(key)
        return super().observe(key, frame)

    def would_flag(self, key: Hashable, frames: Iterable[bytes]) -> bool:
        self.n = self.window(key)
        return super().would_flag(key, frames)

    def observe_all(self, key: Hashable, frames: Sequence[bytes]) -> bool:
        # frame by frame: each observation may end the learning and change the window
        if self.would_flag(key, frames):
            return False
        for frame in frames:
            self.observe(key, frame)
        return True

    def window_for(self, repeats: int, pairs: int) -> int:
        """The window for ``repeats`` of ``pairs`` consecutive frames being repeats."""
        p_up = wilson_upper(repeats, pairs, self.WILSON_Z)
        if p_up >= 1.0:
            return self.ceiling
        n = 1 + math.ceil(math.log(self.false_alarm) / math.log(p_up))
        return max(2, min(self.ceiling, n))


def wilson_upper(successes: int, trials: int, z: float) -> float:
    """The Wilson score interval's upper end for a probability seen ``successes`` times in
    ``trials`` (unlike ``successes / trials``, above 0 when nothing was seen)."""
    p = successes / trials
    z2 = z * z
    centre = p + z2 / (2 * trials)
    spread = z * math.sqrt(p * (1.0 - p) / trials + z2 / (4 * trials * trials))
    return min(1.0, (centre + spread) / (1.0 + z2 / trials))


VALUE_FLAGS = SampleFlag.SATURATED | SampleFlag.OUT_OF_RANGE | SampleFlag.OVERFLOW
"""Flags saying the chip *measured* something wrong (not a failed transfer, a blank frame or
a missing measurement): what the chip's own filter then carries into its next outputs."""
_VALUE_BITS = int(VALUE_FLAGS)
"""``VALUE_FLAGS`` as a plain int: ``int(flags) & _VALUE_BITS`` is one C operation, where
``flags & VALUE_FLAGS`` builds a SampleFlag through the enum machinery (every output)."""


def iir_memory_outputs(coefficient: int, bits: int) -> int:
    """Outputs after a wrong input that an IIR filter ``y += (x - y) / coefficient`` (the
    Bosch barometers' filter, BMP280 datasheet 3.4.3) can still carry it by one LSB or more.

    The wrong input is at most the ADC's whole ``bits``-bit span off; each output keeps
    ``(coefficient - 1) / coefficient`` of what is left, so it fades below one LSB after
    ``bits ln 2 / ln(coefficient / (coefficient - 1))`` outputs (coefficient 4, 20 bits: 49).
    0 or 1: no filter, no memory."""
    if coefficient <= 1:
        return 0
    return math.floor(bits * math.log(2.0) / math.log(coefficient / (coefficient - 1))) + 1


class FilterMemory:
    """The memory of a chip's own filters, per key (a channel, or one key for channels the
    chip filters together).

    ``flag(key, t_ns, flags)`` is called with every output the driver decodes and the flags
    it gave it. An output carrying one of ``VALUE_FLAGS`` arms the key: the outputs of the
    next ``outputs[key]`` output periods (by time, so an output lost to a bus error still
    counts as one the chip made) get ``FILTER_SETTLING``; a later wrong output arms it
    again. ``forget()`` is for a driver that reset the chip's filter (a write that
    re-initialises it, as the BMP280's config register does)."""

    def __init__(self, outputs: Mapping[Any, int], period_ns: Mapping[Any, int]) -> None:
        self.outputs = dict(outputs)
        self.period_ns = dict(period_ns)
        self._until_ns: dict[Hashable, int] = {}

    def flag(self, key: Hashable, t_ns: int, flags: SampleFlag) -> SampleFlag:
        """``FILTER_SETTLING`` when the output at ``t_ns`` may still carry a wrong one."""
        n = self.outputs.get(key, 0)
        if not n:
            return SampleFlag.OK
        until = self._until_ns.get(key)
        # An output the window covers is settling even when it carries a wrong measurement
        # itself: the channels filtered together (the BMP280's temperature beside a wrong
        # pressure) are not flagged by that measurement, but still carry the earlier one.
        settling = SampleFlag.FILTER_SETTLING if until is not None and t_ns <= until \
            else SampleFlag.OK
        if int(flags) & _VALUE_BITS:
            self.arm(key, t_ns)
            return settling
        if until is not None and not settling:
            del self._until_ns[key]
        return settling

    def quiet(self, key: Hashable) -> bool:
        """No window is open for ``key``: ``flag`` of an output without ``VALUE_FLAGS``
        returns OK and changes nothing (a driver decoding a burst at once skips it)."""
        return key not in self._until_ns

    def arm(self, key: Hashable, t_ns: int) -> None:
        """The chip's filter took in a wrong measurement at ``t_ns`` (one ``flag`` arms on by
        itself, or one the driver flagged otherwise: a conversion hung on an old value,
        FROZEN): the next ``outputs[key]`` output periods are FILTER_SETTLING."""
        n = self.outputs.get(key, 0)
        if not n:
            return
        period = self.period_ns[key]
        # Half a period more: an output polled a little late is still one of the n.
        # A new wrong measurement never shortens the window an earlier one opened.
        self._until_ns[key] = max(self._until_ns.get(key, 0), t_ns + n * period + period // 2)

    def forget(self) -> None:
        """The chip's filters were re-initialised: nothing earlier can reach the next output."""
        self._until_ns.clear()


RAIL_SHARE = 0.9
"""``LowPassWatch``: an input the filter's inverse puts within 10 % of the rail (or beyond)
is taken as one the chip's ADC cut at its rail. An honest input that close to the rail is
nearly clipped anyway; the margin covers noise and motion the inverse amplifies."""


def lowpass_coefficient(bandwidth_hz: float, period_s: float) -> float:
    """The share of its previous output a first-order low-pass of 3 dB ``bandwidth_hz``
    keeps one output period ``period_s`` later: exp(-2 pi bandwidth period)."""
    return math.exp(-2.0 * math.pi * bandwidth_hz * period_s)


def lowpass_settling_outputs(bandwidth_hz: float, output_rate_hz: float,
                             settled_share: float) -> int:
    """Outputs after one input at the rail that a first-order low-pass of ``bandwidth_hz``
    (output at ``output_rate_hz``) can still carry it by ``settled_share`` of the full scale
    or more: the input, at most two full scales from the truth, enters the output with
    weight 1 - a and fades by a per output (``lowpass_coefficient``), so the n-th output
    after it keeps at most 2 (1 - a) a^n full scales (10 Hz at 200 Hz, settled at 0.3 % of
    the full scale: 20)."""
    return _settling_outputs(lowpass_coefficient(bandwidth_hz, 1.0 / output_rate_hz),
                             settled_share)


def _settling_outputs(a: float, settled_share: float) -> int:
    """``lowpass_settling_outputs`` of a filter keeping ``a`` per output."""
    entered = 2.0 * (1.0 - a)
    if a <= 0.0 or entered <= settled_share:
        return 0
    return math.floor(math.log(entered / settled_share) / -math.log(a))


class LowPassWatch:
    """A chip's digital low-pass (an IMU's gyro or accelerometer filter) and the outputs a
    wrong input can still be in, per key (a channel).

    The datasheets give the filter's 3 dB bandwidth only; it is taken as the first-order
    low-pass of that bandwidth at the output rate: each output keeps ``a`` of the one
    before and takes ``1 - a`` of the input (``lowpass_coefficient``). The chip's ADC cuts
    its input at the rail before the filter, so a shock beyond the range for one output
    period leaves an output in range (``1 - a`` of the way to the rail) and far off. The
    watch undoes the filter: from the previous output ``g`` periods before, the mean input
    over them is ``(y - a^g y_prev) / (1 - a^g)``; one within ``RAIL_SHARE`` of the rail
    that moved the output by 1 - a of the rest of the way at least (an honest input held
    near the rail moves it little) is a rail input, its output ``FILTER_SETTLING`` (value
    as read). After a rail input
    (hidden, or an output at the rail itself, flagged ``SATURATED`` by the driver) the
    watch keeps a bound on what the filter still carries, in full scales: it adds
    ``2 (1 - a^g)`` (the input at most two full scales from the truth) and fades by ``a``
    per period, and the outputs are ``FILTER_SETTLING`` until it is below the key's
    ``settled_counts``: what the validity model already tolerates of a valid reading of
    that chip (its driver's specified offset), so an output handed back is no further off
    than the chip may read anyway. Outputs lost to bus errors count as periods the chip
    filtered."""

    def __init__(self, coefficient: Mapping[Any, float], period_ns: Mapping[Any, int],
                 rail_counts: int, settled_counts: Mapping[Any, float]) -> None:
        self.coefficient = dict(coefficient)
        self.period_ns = dict(period_ns)
        self.rail_counts = rail_counts
        self.settled_share = {key: settled_counts[key] / rail_counts for key in coefficient}
        """Per key: what the filter may still carry of a rail input once its outputs are
        valid again, in full scales."""
        self._one = {key: (a, RAIL_SHARE * rail_counts * (1.0 - a),
                           (1.0 - RAIL_SHARE) * rail_counts * (1.0 - a),
                           self.period_ns[key] + self.period_ns[key] // 2)
                     for key, a in self.coefficient.items() if a > 0.0}
        """Per key with a filter, for an output one period after the last: (a, the rail
        input's limit on ``y - a y_prev``, how far a rail input moves the output at least:
        1 - a of the way from within RAIL_SHARE of the rail, a rail input from nearer the
        rail leaving a trace below that, within what a reading there may be off anyway;
        and the most time between two outputs one period apart)."""
        self._last: dict[Hashable, tuple[int, Sequence[int], int, Sequence[int]]] = {}
        """Per key: the latest output's time stamp and counts (the filter's previous state),
        then the one's before it (the change per output before a gap; -1, () at first)."""
        self._railed: set[Hashable] = set()
        """Keys whose latest output was a rail input (hidden or at the rail)."""
        self._bound: dict[Hashable, tuple[int, float]] = {}
        """Per key: (time stamp, what the filter may still carry then, in full scales)."""

    def settling_outputs(self, key: Hashable) -> int:
        """Outputs after one rail input that are FILTER_SETTLING (``lowpass_settling_outputs``)."""
        return _settling_outputs(self.coefficient[key], self.settled_share[key])

    def rail_input(self, key: Hashable, t_ns: int, counts: Sequence[int]) -> bool:
        """Whether the filter's inverse puts the input behind the output ``counts`` at
        ``t_ns`` at the rail (nothing is recorded)."""
        last = self._last.get(key)
        return last is not None and self._hidden(key, t_ns, counts, last)

    def _hidden(self, key: Hashable, t_ns: int, counts: Sequence[int],
                last: tuple[int, Sequence[int], int, Sequence[int]]) -> bool:
        a, limit, jump, most_ns = self._one[key]
        t_last, previous = last[0], last[1]
        if t_ns - t_last >= most_ns:
            return self._hidden_in_gap(key, round((t_ns - t_last) / self.period_ns[key]),
                                       counts, last)
        # the input at the rail, and far from where the output was or still there after a
        # rail input: an honest input that comes near the rail (a fast roll) moves the
        # output little from one output to the next
        if key in self._railed:
            jump = 0.0
        for y, p in zip(counts, previous, strict=True):
            if abs(y - a * p) >= limit and abs(y - p) >= jump:
                return True
        return False

    def _hidden_in_gap(self, key: Hashable, g: int, counts: Sequence[int],
                       last: tuple[int, Sequence[int], int, Sequence[int]]) -> bool:
        """Whether ``g`` periods after the last output (the outputs between unseen: a host
        stall, a failed read) one of the unseen inputs may have been at the rail. The mean
        input over the gap cannot tell: one rail input among them moves it by its weight
        only ((1 - a) a^j for the input j outputs back, 0.72 for the latest at the GY-91's
        41 Hz). So the output is held against the last one carried on at the change per
        output seen before it: a rail input that still adds the key's settled counts or more
        shows as a departure of that much beyond what the same change again allows; honest
        motion that bends that hard after a gap is flagged too
        (availability, not trust)."""
        t_last, previous, t_before, before = last
        slope = [0.0, 0.0, 0.0] if t_before < 0 else \
            [(p - b) / max(1, round((t_last - t_before) / self.period_ns[key]))
             for p, b in zip(previous, before, strict=True)]
        allowed = self.settled_share[key] * self.rail_counts
        return any(abs(y - p - g * d) >= allowed + g * abs(d)
                   for y, p, d in zip(counts, previous, slope, strict=True))

    def observe(self, key: Hashable, t_ns: int, counts: Sequence[int],
                flags: SampleFlag) -> SampleFlag:
        """The FILTER_SETTLING flag of the output ``counts`` (three axes, not changed
        afterwards: kept as the filter's previous output) at ``t_ns`` whose driver gave it
        ``flags`` (``SATURATED``, ``OUT_OF_RANGE`` or ``OVERFLOW``: an output at the rail, a
        rail input). A key without a filter (``a`` 0) is never flagged."""
        one = self._one.get(key)
        if one is None:
            return SampleFlag.OK
        last = self._last.get(key)
        hidden = self._record(key, t_ns, counts, last, one)
        bound = self._bound.get(key)
        wrong = hidden or bool(int(flags) & _VALUE_BITS)
        if bound is None and not wrong:
            return SampleFlag.OK
        return self._settle(key, t_ns, last, bound, hidden=hidden, wrong=wrong)

    def _record(self, key: Hashable, t_ns: int, counts: Sequence[int],
                last: tuple[int, Sequence[int], int, Sequence[int]] | None,
                one: tuple[float, float, float, int]) -> bool:
        """Keep ``counts`` as the filter's previous output; whether its input was a rail
        input (``_hidden``)."""
        if last is None:
            self._last[key] = (t_ns, counts, -1, ())
            return False
        self._last[key] = (t_ns, counts, last[0], last[1])
        a, limit, jump, most_ns = one
        if t_ns - last[0] >= most_ns or key in self._railed:
            return self._hidden(key, t_ns, counts, last)
        # every output of a quiet filter takes this way: written out
        y0, y1, y2 = counts
        p0, p1, p2 = last[1]
        return (abs(y0 - a * p0) >= limit and abs(y0 - p0) >= jump) \
            or (abs(y1 - a * p1) >= limit and abs(y1 - p1) >= jump) \
            or (abs(y2 - a * p2) >= limit and abs(y2 - p2) >= jump)

    def _settle(self, key: Hashable, t_ns: int,
                last: tuple[int, Sequence[int], int, Sequence[int]] | None,
                bound: tuple[int, float] | None, *, hidden: bool, wrong: bool) -> SampleFlag:
        """The bound on what the filter still carries, moved to ``t_ns`` (a ``wrong``
        input adds to it), and the output's flag."""
        if wrong:
            self._railed.add(key)
        else:
            self._railed.discard(key)
        a = self.coefficient[key]
        period = self.period_ns[key]
        carried = 0.0 if bound is None else bound[1] * a ** ((t_ns - bound[0]) / period)
        settling = carried >= self.settled_share[key]
        if wrong:
            g = 1 if last is None else max(1, round((t_ns - last[0]) / period))
            self._bound[key] = (t_ns, carried + 2.0 * (1.0 - a ** g))
            return SampleFlag.FILTER_SETTLING if hidden or settling else SampleFlag.OK
        if not settling:
            del self._bound[key]
            return SampleFlag.OK
        return SampleFlag.FILTER_SETTLING

    def quiet(self, key: Hashable) -> bool:
        """No bound is open for ``key`` (a rail input may still be hidden in the next output:
        a driver decoding a burst at once asks ``quiet_block`` instead)."""
        return key not in self._bound

    def quiet_block(self, key: Hashable, counts: npt.NDArray[np.int16],
                    stamps_ns: Sequence[int]) -> bool:
        """Whether ``observe`` of each row of ``counts`` (n x 3, at ``stamps_ns``) in turn
        would flag none and arm nothing, with no word at the rail: then the block is taken
        as observed (its last row becomes the filter's previous output) and True returned;
        else nothing is observed (the driver observes it row by row)."""
        if key not in self._one or not len(stamps_ns):
            return True
        if key in self._bound or key in self._railed:
            return False
        y = counts.astype(np.float64)
        rail = self.rail_counts
        if float(np.abs(y).max()) >= rail:
            return False
        last = self._last.get(key)
        if last is None:
            previous, times = y[:-1], np.asarray(stamps_ns, np.float64)
            current = y[1:]
        else:
            previous = np.vstack([np.asarray(last[1], np.float64)[None, :], y[:-1]])
            times = np.asarray([last[0], *stamps_ns], np.float64)
            current = y
        if len(current):
            g = np.maximum(1.0, np.rint(np.diff(times) / self.period_ns[key]))
            if float(g.max()) > 1.0:
                return False  # a gap: row by row (``_hidden_in_gap``)
            kept = self.coefficient[key] ** g
            limit = RAIL_SHARE * rail * (1.0 - kept)
            if bool(((np.abs(current - kept[:, None] * previous) >= limit[:, None])
                     & (np.abs(current - previous) >= self._one[key][2])).any()):
                return False
        newest = (int(stamps_ns[-1]), tuple(int(v) for v in counts[-1]))
        if len(stamps_ns) > 1:
            self._last[key] = (*newest, int(stamps_ns[-2]), tuple(int(v) for v in counts[-2]))
        else:
            self._last[key] = (*newest, -1, ()) if last is None else (*newest, *last[:2])
        return True

    def forget(self) -> None:
        """The chip's filters were re-initialised (a reset): nothing earlier reaches the
        next output, and there is no previous output to undo the filter from."""
        self._bound.clear()
        self._last.clear()
        self._railed.clear()


R = TypeVar("R")


class NewLevel(Generic[R]):
    """Refused readings in a row that agree with one another, until they are a new level.

    A check that holds each reading against the last valid one (the reference) refuses a
    disturbed reading, and a refused reading is no new reference, so one disturbance never
    moves the bound for the honest readings after it. The reference itself may be wrong,
    though (the first reading, or a real change while readings were lost); then every honest
    reading after it is refused. ``refused(reading)`` is called with each reading the check
    refused: ``confirm`` of them in a row, each agreeing with the one before it
    (``agree(earlier, later)``: the check's own rule), are a new level, and the call that
    completes the run answers True (the caller takes that reading as its new reference).
    A reading that does not agree with the one before it starts a new run. So a wrong
    reference costs at most ``confirm - 1`` honest readings (refused, never passed as wrong
    ones), and up to ``confirm - 1`` disturbed readings in a row that agree are still
    refused. ``clear()`` when the check accepted a reading: the run must be unbroken."""

    def __init__(self, confirm: int, agree: Callable[[R, R], bool]) -> None:
        if confirm < 2:
            raise ValueError(f"a new level needs at least 2 readings to confirm it, got "
                             f"{confirm}")
        self.confirm = confirm
        self.agree = agree
        self._run: list[R] = []

    def refused(self, reading: R) -> bool:
        """Add a refused reading; True when it completes a run of ``confirm`` that agree."""
        if self._run and not self.agree(self._run[-1], reading):
            self._run.clear()
        self._run.append(reading)
        if len(self._run) < self.confirm:
            return False
        self._run.clear()
        return True

    def clear(self) -> None:
        """The check accepted a reading: a run of refused ones is broken."""
        self._run.clear()


class StepWatch:
    """Flags a reading that moved further from the last valid one than the quantity can.

    ``observe(t_ns, value)`` is called with every reading the driver would otherwise emit
    valid. It allows ``max_rate_per_s`` times the time since the last valid reading plus
    ``noise`` (what two readings of an unchanged quantity can differ by) and returns
    ``IMPLAUSIBLE`` beyond that. A reading the bound refuses is no new reference, so one
    disturbed conversion never moves the bound for the honest readings after it.

    The reference itself may be wrong (the first reading after the driver started, or a real
    change while readings were lost): ``confirm`` refused readings in a row that agree with
    one another within the same bound are a new level (``NewLevel``), and the last of them
    is valid and the new reference. So a wrong reference costs at most ``confirm - 1``
    honest readings (flagged, never passed as wrong ones), and up to ``confirm - 1`` equal
    disturbed readings in a row are still refused. The history survives a restart of the
    chip: the bound grows with the time since the reference, so a long outage checks little.
    """

    def __init__(self, max_rate_per_s: float, noise: float, confirm: int = 3) -> None:
        if max_rate_per_s <= 0 or noise < 0 or confirm < 2:
            raise ValueError(
                f"a step watch needs max_rate_per_s > 0, noise >= 0 and confirm >= 2, got "
                f"{max_rate_per_s}, {noise}, {confirm}")
        self.max_rate_per_s = max_rate_per_s
        self.noise = noise
        self.confirm = confirm
        self._reference: tuple[int, float] | None = None
        self._new_level = NewLevel(confirm, self._agree)
        self.refused = 0
        """Readings flagged IMPLAUSIBLE so far."""

    def _agree(self, earlier: tuple[int, float], later: tuple[int, float]) -> bool:
        dt_s = max(0, later[0] - earlier[0]) * 1e-9
        return abs(later[1] - earlier[1]) <= self.max_rate_per_s * dt_s + self.noise

    def observe(self, t_ns: int, value: float) -> SampleFlag:
        """``IMPLAUSIBLE`` when ``value`` at ``t_ns`` cannot follow the last valid reading."""
        reading = (t_ns, value)
        if self._reference is None or self._agree(self._reference, reading):
            self._reference = reading
            self._new_level.clear()
            return SampleFlag.OK
        if self._new_level.refused(reading):
            self._reference = reading
            return SampleFlag.OK
        self.refused += 1
        return SampleFlag.IMPLAUSIBLE
