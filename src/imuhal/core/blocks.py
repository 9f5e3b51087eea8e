"""Blocks: n frames of one stream, as arrays, with the facts they were taken with.

A chip's FIFO hands over several frames at once (the MPU-9250's: up to 36), each a period
after the one before. A :class:`Block` carries them together: the device, a base time
stamp (``t0_ns``, int ns on the pipeline clock) and per-frame offsets from it, the values
as a float64 array in the quantity's SI unit (``(n, 3)`` for a vector, ``(n, 1)`` for a
scalar) in ``frame``, the flags of each frame, and the :class:`~imuhal.core.streams.StreamSpec`
the stream ran with (its unit, full scale and rate). The pipeline's stages (validity,
calibration, the mount rotation) and ``Estimator.update_block`` run once per block.

One frame is the common case (a register poll): then a block is a thin wrapper around the
one :class:`~imuhal.core.samples.Sample` the driver built, and the stages use it directly;
its arrays are built only when asked for. Either way :meth:`Block.samples` gives the frames
as one-row ``Sample`` views, what sinks, ``Pipeline.events()`` and embedding code see.
"""

from __future__ import annotations

from collections.abc import Iterable, Iterator, Sequence
from dataclasses import fields
from typing import Any

import numpy as np
import numpy.typing as npt

from imuhal.core.quantities import Quantity
from imuhal.core.samples import Frame, Sample, SampleFlag, ScalarSample, VectorSample
from imuhal.core.streams import StreamSpec

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int64]

_BASE_FIELDS = frozenset(("t_ns", "device", "flags", "frame"))


def _value_field(kind: type[Sample]) -> str | None:
    """The one value field of a vector or scalar sample class (``gyro_rad_s``), or None
    for a class that carries more than one value (a GNSS fix, an airspeed with its
    accuracy): such samples travel in blocks as their rows only. (Worked out once per
    class: every block of several frames asks.)"""
    try:
        return _VALUE_FIELDS[kind]
    except KeyError:
        pass
    name = None
    if issubclass(kind, VectorSample | ScalarSample):
        names = [f.name for f in fields(kind) if f.name not in _BASE_FIELDS]
        name = names[0] if len(names) == 1 else None
    _VALUE_FIELDS[kind] = name
    return name


_VALUE_FIELDS: dict[type, str | None] = {}


class Block:
    """n frames of one stream of one device, oldest first (see the module docstring).

    Built from arrays (:meth:`from_arrays`, a FIFO reader) or from the driver's samples
    (:meth:`from_samples`); each form is derived from the other on first use. Blocks are
    not modified once built: a stage makes a new one (:meth:`with_values`,
    :meth:`with_flags`)."""

    __slots__ = (
        "_flagged",
        "_flags",
        "_offsets",
        "_rows",
        "_t",
        "_t0",
        "_values",
        "device",
        "frame",
        "kind",
        "spec",
    )

    def __init__(self, kind: type[Sample], device: str, *, frame: Frame | None,
                 spec: StreamSpec | None, rows: list[Sample] | None = None,
                 t0_ns: int = 0, offsets_ns: IntArray | None = None,
                 values: FloatArray | None = None, flags: IntArray | None = None) -> None:
        self.kind = kind
        """The sample class of the one-row views (``GyroSample`` ...): the quantity."""
        self.device = device
        self.frame = frame
        """The axes of a vector block's values (None for a scalar)."""
        self.spec = spec
        """The stream's spec at the time the frames were taken (None: the driver declares
        none)."""
        self._rows = rows
        self._t0 = t0_ns if rows is None else rows[0].t_ns
        self._offsets = offsets_ns
        self._values = values
        self._flags = flags
        self._flagged: bool | None = None
        self._t: IntArray | None = None

    # -- construction -----------------------------------------------------------------

    @classmethod
    def from_samples(cls, samples: Sequence[Sample], spec: StreamSpec | None = None
                     ) -> Block:
        """A block of ``samples`` (one device, one sample class, time order), which stay
        its one-row views."""
        if not samples:
            raise ValueError("a block holds at least one frame")
        first = samples[0]
        kind = type(first)
        for s in samples:
            if type(s) is not kind or s.device != first.device:
                raise ValueError(f"a block holds one stream: {first.device} "
                                 f"{kind.__name__}, got {s.device} {type(s).__name__}")
        frame = first.frame if isinstance(first, VectorSample) else None
        if frame is not None and any(getattr(s, "frame", None) is not frame for s in samples):
            raise ValueError(f"{first.device} {kind.__name__}: frames in one block are in "
                             f"one frame of axes")
        return cls(kind, first.device, frame=frame, spec=spec, rows=list(samples))

    @classmethod
    def of_sample(cls, sample: Sample, spec: StreamSpec | None = None) -> Block:
        """A block of one frame: ``sample`` (the common case, built for every reading of a
        register poll, so without the checks of :meth:`from_samples`)."""
        b = _new(cls)
        b.kind = type(sample)
        b.device = sample.device
        b.frame = getattr(sample, "frame", None)
        b.spec = spec
        b._rows = [sample]
        b._t0 = sample.t_ns
        b._offsets = b._values = b._flags = b._t = None
        b._flagged = bool(sample.flags)
        return b

    @classmethod
    def from_arrays(cls, kind: type[Sample], device: str, t0_ns: int, offsets_ns: IntArray,
                    values: FloatArray, flags: IntArray, *, frame: Frame | None,
                    spec: StreamSpec | None = None) -> Block:
        """A block of ``len(offsets_ns)`` frames: time stamps ``t0_ns + offsets_ns`` (int64
        ns, non-decreasing), ``values`` (n, 3) or (n, 1) float64 in ``kind``'s unit,
        ``flags`` (n,) SampleFlag bits."""
        if _value_field(kind) is None:
            raise ValueError(f"{kind.__name__} carries more than one value: build its "
                             f"block from samples")
        n = len(offsets_ns)
        width = 3 if issubclass(kind, VectorSample) else 1
        if n == 0 or values.shape != (n, width) or flags.shape != (n,):
            raise ValueError(f"{device} {kind.__name__}: {n} offsets, values "
                             f"{values.shape} and flags {flags.shape} do not make "
                             f"{n} frames of {width} values")
        if n > 1 and bool(np.any(np.diff(offsets_ns) < 0)):
            raise ValueError(f"{device} {kind.__name__}: frame offsets go back in time")
        return cls(kind, device, frame=frame, spec=spec, t0_ns=t0_ns,
                   offsets_ns=np.asarray(offsets_ns, dtype=np.int64),
                   values=np.asarray(values, dtype=np.float64),
                   flags=np.asarray(flags, dtype=np.int64))

    @classmethod
    def regular(cls, kind: type[Sample], device: str, t0_ns: int, period_ns: int,
                values: FloatArray, flags: IntArray | None = None, *,
                frame: Frame | None, spec: StreamSpec | None = None) -> Block:
        """Frames a fixed ``period_ns`` apart from ``t0_ns`` (a FIFO's), all OK unless
        ``flags`` says otherwise."""
        n = len(values)
        offsets = np.arange(n, dtype=np.int64) * period_ns
        return cls.from_arrays(kind, device, t0_ns, offsets, values,
                               np.zeros(n, np.int64) if flags is None else flags,
                               frame=frame, spec=spec)

    def with_values(self, values: FloatArray, frame: Frame | None) -> Block:
        """The same frames (times, flags) with new values in ``frame``."""
        # slots set directly (every calibrated block is made here): __init__'s keywords
        # cost more than the rest
        b = _new(Block)
        b.kind = self.kind
        b.device = self.device
        b.frame = frame
        b.spec = self.spec
        b._rows = None
        b._t0 = self._t0
        b._offsets = self.offsets_ns
        b._values = values
        b._flags = self.flags
        b._flagged = self._flagged
        b._t = self._t  # the same stamps
        return b

    def with_flags(self, flags: IntArray) -> Block:
        """The same frames with ``flags`` (n,) instead of theirs."""
        b = Block(self.kind, self.device, frame=self.frame, spec=self.spec,
                  t0_ns=self._t0, offsets_ns=self.offsets_ns, values=self.values,
                  flags=flags)
        b._t = self._t  # the same stamps
        return b

    def select(self, keep: npt.NDArray[np.bool_]) -> Block | None:
        """The frames where ``keep`` (n,) is true, as a block (this one when all are; None
        when none is)."""
        if bool(keep.all()):
            return self
        if not bool(keep.any()):
            return None
        if self._rows is not None:
            return Block.from_samples([s for s, k in zip(self._rows, keep.tolist(),
                                                         strict=True) if k], self.spec)
        offsets = self.offsets_ns[keep]
        return Block(self.kind, self.device, frame=self.frame, spec=self.spec,
                     t0_ns=self._t0 + int(offsets[0]), offsets_ns=offsets - offsets[0],
                     values=self.values[keep], flags=self.flags[keep])

    # -- what a block holds -------------------------------------------------------------

    @property
    def quantity(self) -> Quantity:
        return self.kind.channel

    @property
    def unit(self) -> str:
        """The SI unit of every value (the quantity's)."""
        return self.kind.channel.unit

    @property
    def t0_ns(self) -> int:
        """The first frame's time stamp (ns, pipeline clock)."""
        return self._t0

    def __len__(self) -> int:
        if self._rows is not None:
            return len(self._rows)
        assert self._offsets is not None
        return len(self._offsets)

    @property
    def offsets_ns(self) -> IntArray:
        """(n,) int64: each frame's time stamp minus ``t0_ns``."""
        if self._offsets is None:
            assert self._rows is not None
            self._offsets = np.fromiter((s.t_ns - self._t0 for s in self._rows), np.int64,
                                        len(self._rows))
        return self._offsets

    @property
    def t_ns(self) -> IntArray:
        """(n,) int64 time stamps (ns; worked out once: every stage asks)."""
        if self._t is None:
            self._t = self.offsets_ns + self._t0
        return self._t

    @property
    def values(self) -> FloatArray:
        """(n, 3) or (n, 1) float64 in ``unit`` (NaN rows for a class with no one value)."""
        if self._values is None:
            assert self._rows is not None
            self._values = np.array([_row_values(s) for s in self._rows], dtype=np.float64)
        return self._values

    @property
    def flagged(self) -> bool:
        """True when some frame has a flag (``flags.any()``, worked out once: a block is
        not modified once built, and several stages ask)."""
        flagged = self._flagged
        if flagged is None:
            # count_nonzero is C all the way (ndarray.any goes through a Python wrapper)
            flagged = self._flagged = bool(np.count_nonzero(self.flags))
        return flagged

    @property
    def flags(self) -> IntArray:
        """(n,) int64 SampleFlag bits per frame (0: may be fused)."""
        if self._flags is None:
            assert self._rows is not None
            self._flags = np.fromiter((int(s.flags) for s in self._rows), np.int64,
                                      len(self._rows))
        return self._flags

    @property
    def has_arrays(self) -> bool:
        """Its frames can be held as arrays: the sample class carries one value (a GNSS fix,
        with several, travels as its rows only, and stages check those row by row)."""
        return _value_field(self.kind) is not None

    @property
    def has_rows(self) -> bool:
        """The one-row views exist already (a block built from samples, or asked for them):
        a one-frame stage may work on the row instead of building arrays."""
        return self._rows is not None

    def samples(self) -> list[Sample]:
        """The frames as one-row ``Sample`` views, oldest first (built once)."""
        if self._rows is None:
            self._rows = list(self._build_rows())
        return self._rows

    def __iter__(self) -> Iterator[Sample]:
        return iter(self.samples())

    def _build_rows(self) -> Iterable[Sample]:
        field_name = _value_field(self.kind)
        assert field_name is not None  # arrays only for one-value classes (from_arrays)
        t = self.t_ns.tolist()
        flags = self.flags.tolist()
        values = self.values.tolist()
        kind: Any = self.kind
        if issubclass(self.kind, VectorSample):
            build = kind.build
            frame = self.frame
            return [build(ti, self.device, _flag(fi), frame, (v[0], v[1], v[2]))
                    for ti, fi, v in zip(t, flags, values, strict=True)]
        return [kind(t_ns=ti, device=self.device, flags=_flag(fi), **{field_name: v[0]})
                for ti, fi, v in zip(t, flags, values, strict=True)]

    def __repr__(self) -> str:
        return (f"Block({self.device} {self.kind.__name__}, {len(self)} frames from "
                f"t={self._t0} ns, frame={self.frame})")


_new = object.__new__
_FLAGS: dict[int, SampleFlag] = {0: SampleFlag.OK}


def _flag(bits: int) -> SampleFlag:
    """``SampleFlag(bits)``, each value made once (an enum call costs a microsecond)."""
    flag = _FLAGS.get(bits)
    if flag is None:
        flag = _FLAGS[bits] = SampleFlag(bits)
    return flag


def _distinct_streams(samples: Sequence[Sample]) -> bool:
    """No two of ``samples`` (at most four) belong to one stream."""
    kinds = [(type(s), s.device) for s in samples]
    return all(kinds[i] not in kinds[i + 1:] for i in range(len(kinds) - 1))


def _row_values(sample: Sample) -> tuple[float, ...]:
    if isinstance(sample, VectorSample):
        return sample.vector
    if isinstance(sample, ScalarSample):
        return (sample.scalar,)
    return (float("nan"),)


def blocks_of(samples: Sequence[Sample]) -> list[Block]:
    """``samples`` of one poll as blocks: one per (device, sample class, frame), in the
    order each first appears, frames in the order given. A register poll's three samples
    make three one-frame blocks; a FIFO read of n frames makes blocks of n frames."""
    n = len(samples)
    if n < 2 or (n <= 4 and _distinct_streams(samples)):
        return [Block.of_sample(s) for s in samples]  # a register poll: one of each
    groups: dict[tuple[str, type, object], list[Sample]] = {}
    for s in samples:
        key = (s.device, type(s), getattr(s, "frame", None))
        group = groups.get(key)
        if group is None:
            groups[key] = [s]
        else:
            group.append(s)
    return [Block.from_samples(group) for group in groups.values()]


def interleaved(blocks: Sequence[Block]) -> list[Sample]:
    """The frames of ``blocks`` as one list in time order, blocks in the order given for
    frames of one instant (a FIFO's accelerometer, temperature and gyro frame of one
    instant come out together, as the chip's frame held them)."""
    if len(blocks) == 1:
        return blocks[0].samples()
    if all(len(b) == 1 for b in blocks):
        return [b.samples()[0] for b in blocks]
    keyed = [(s.t_ns, i, j, s) for i, b in enumerate(blocks)
             for j, s in enumerate(b.samples())]
    keyed.sort()  # (time, block, frame) is unique: the samples themselves are never compared
    return [k[3] for k in keyed]
