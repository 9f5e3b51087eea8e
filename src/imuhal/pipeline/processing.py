"""The per-sample steps between a driver and the estimators, as plain functions.

Order (fixed, docs/units-and-frames.md): validity check -> calibration (sensor frame) ->
rotation chip -> body. A flagged sample goes through unchanged apart from the rotation, so
sinks can still log it; it is never handed to an estimator.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Protocol

import numpy as np

from imuhal.calibration.model import (
    AccelCalibration,
    DeviceCalibration,
    GyroCalibration,
    MagCalibration,
    VectorCalibration,
)
from imuhal.core.blocks import Block, IntArray
from imuhal.core.frames import FloatArray
from imuhal.core.samples import (
    AccelSample,
    Frame,
    GyroSample,
    MagSample,
    Sample,
    SampleFlag,
    ScalarSample,
    Vec3,
    VectorSample,
)


class _Correction(Protocol):
    """A calibration record: corrects a sensor-frame vector."""

    def apply(self, raw: Vec3) -> Vec3: ...


def values_of(sample: Sample) -> tuple[float, ...]:
    """The sample's numbers (a vector's three components, or the scalar)."""
    if isinstance(sample, VectorSample):
        return sample.vector
    if isinstance(sample, ScalarSample):
        return (sample.scalar,)
    return ()


def validity_flags(sample: Sample, full_scale: float | None, last_t_ns: int | None
                   ) -> SampleFlag:
    """The pipeline's part of validity, on top of what the driver flagged: every value
    finite (else NAN), none beyond ``full_scale`` (the chip's configured full scale, SI;
    None: not declared; else OUT_OF_RANGE), and not older than ``last_t_ns``, the last valid
    sample of the same device and quantity (else OUT_OF_ORDER). This is the only NaN check."""
    flags = sample.flags
    values = values_of(sample)
    if len(values) == 3:  # a vector (every IMU reading): the same tests written out
        x, y, z = values
        # x - x is 0.0 for a finite x and NaN for an infinite or NaN one
        if (x - x) + (y - y) + (z - z) != 0.0:
            flags |= SampleFlag.NAN
        elif full_scale is not None and not (
                -full_scale <= x <= full_scale and -full_scale <= y <= full_scale
                and -full_scale <= z <= full_scale):  # |v| > full scale, no builtin calls
            flags |= SampleFlag.OUT_OF_RANGE
    elif not all(map(math.isfinite, values)):
        flags |= SampleFlag.NAN
    elif full_scale is not None and values and max(map(abs, values)) > full_scale:
        flags |= SampleFlag.OUT_OF_RANGE
    if last_t_ns is not None and sample.t_ns < last_t_ns:
        flags |= SampleFlag.OUT_OF_ORDER
    return flags


def _record(sample: VectorSample, calibration: DeviceCalibration | None) -> _Correction | None:
    """The calibration record of the sample's quantity, if any."""
    if calibration is None:
        return None
    return _record_of(type(sample), sample.channel.name, calibration)


def _rotate(m: FloatArray | list[list[float]], v: Vec3) -> Vec3:
    """``m @ v`` in plain floats: cheaper than a numpy product for one vector (every sample
    comes through here). The same floats as numpy's own loop, signed zeros included; BLAS,
    which numpy may use instead, can differ in the last bit for a matrix that is not a
    signed permutation. ``m`` may be given as nested lists of floats already."""
    rows = m if type(m) is list else np.asarray(m, dtype=float).tolist()
    (a, b, c), (d, e, f), (g, h, i) = rows
    x, y, z = v
    # Each sum starts from +0.0 as numpy's does, so an exact zero keeps numpy's sign (+0.0).
    return (0.0 + a * x + b * y + c * z, 0.0 + d * x + e * y + f * z,
            0.0 + g * x + h * y + i * z)


def calibrate_to_body(sample: Sample, calibration: DeviceCalibration | None,
                      chip_to_body: FloatArray | list[list[float]]) -> Sample:
    """Apply the stored calibration of the sample's channel (sensor frame), then rotate the
    vector into the NED body frame; the sample is copied once (copying a frozen sample costs
    more than the arithmetic). Scalar samples pass unchanged."""
    if not isinstance(sample, VectorSample):
        return sample
    record = _record(sample, calibration)
    vector = sample.vector if record is None else record.apply(sample.vector)
    if sample.frame is Frame.BODY_NED:
        return sample if record is None else sample.with_vector(vector, sample.frame)
    return sample.with_vector(_rotate(chip_to_body, vector), Frame.BODY_NED)


# -- the same steps once per block ---------------------------------------------------------

def validity_block(block: Block, full_scale: float | None, last_t_ns: int | None
                   ) -> tuple[Block, int | None]:
    """:func:`validity_flags` for every frame of ``block`` at once; returns the block (the
    same object when no flag was added) and the time of its last valid frame (else
    ``last_t_ns``), which the next block of the stream is checked against.

    One frame built from a sample is checked on the sample (Python floats cost less than
    numpy calls on one row); longer blocks on their arrays, with the same outcome: a frame
    is OUT_OF_ORDER when it is older than the last valid frame before it."""
    if len(block) == 1 and block.has_rows:
        row = block.samples()[0]
        flags = validity_flags(row, full_scale, last_t_ns)
        if flags != row.flags:
            row = row.flagged(flags)
            block = Block.from_samples([row], block.spec)
        return block, (row.t_ns if row.valid else last_t_ns)
    if not block.has_arrays:  # e.g. GNSS fixes a receiver delivered together
        return _validity_rows(block, full_scale, last_t_ns)
    t_ns = block.t_ns
    if len(t_ns) > 1 and _MAX(t_ns[:-1] - t_ns[1:]) > 0:  # a frame older than the one before
        return _validity_rows(block, full_scale, last_t_ns)
    if _all_valid(block, t_ns, full_scale, last_t_ns):
        return block, int(t_ns[-1])  # the common case, in a few numpy calls
    bits = _validity_bits(block, full_scale)
    if last_t_ns is not None:
        # frames in time order: only the last valid frame before the block can be newer
        bits[t_ns < last_t_ns] |= SampleFlag.OUT_OF_ORDER
    valid = bits == 0
    last = int(t_ns[valid][-1]) if bool(valid.any()) else last_t_ns
    if np.array_equal(bits, block.flags):
        return block, last
    return block.with_flags(bits), last


def _all_valid(block: Block, t_ns: IntArray, full_scale: float | None,
               last_t_ns: int | None) -> bool:
    """Every frame of ``block`` (in time order) unflagged, finite, within ``full_scale``
    and not older than ``last_t_ns``: what :func:`validity_block` would leave unflagged,
    tested in a few numpy calls (a NaN or inf fails the comparison)."""
    values = block.values
    if len(t_ns) == 0 or block.flagged or \
            (last_t_ns is not None and int(t_ns[0]) < last_t_ns):
        return False
    if not values.shape[1]:
        return True
    peak = _MAX(np.abs(values), axis=None)  # NaN when some value is
    return bool(peak <= full_scale) if full_scale is not None else bool(np.isfinite(peak))


_MAX = np.maximum.reduce
"""The ufunc's reduction called directly: ``ndarray.max``, ``np.any`` and ``np.diff`` go
through Python wrappers that cost more than the arithmetic on a FIFO read's 8-10 frames."""


def _validity_bits(block: Block, full_scale: float | None) -> IntArray:
    """The block's flags with NAN and OUT_OF_RANGE added (a new array)."""
    values = block.values
    bits: IntArray = np.array(block.flags, dtype=np.int64)
    finite = np.asarray(np.isfinite(values).all(axis=1), dtype=bool)
    bits[~finite] |= SampleFlag.NAN
    if full_scale is not None and values.shape[1]:
        magnitude = np.abs(np.where(finite[:, None], values, 0.0)).max(axis=1)
        bits[finite & (magnitude > full_scale)] |= SampleFlag.OUT_OF_RANGE
    return bits


def _validity_rows(block: Block, full_scale: float | None, last_t_ns: int | None
                   ) -> tuple[Block, int | None]:
    """Frames out of time order inside one block (a driver built it from its samples):
    checked one by one, as they came."""
    rows = []
    for row in block.samples():
        flags = validity_flags(row, full_scale, last_t_ns)
        row = row if flags == row.flags else row.flagged(flags)
        if row.valid:
            last_t_ns = row.t_ns
        rows.append(row)
    return Block.from_samples(rows, block.spec), last_t_ns


def _corrected(record: object, values: FloatArray) -> FloatArray | None:
    """What ``record.apply`` computes, on every row of ``values`` (n, 3), in the same order
    of operations (the same floats); None for a record kind not known here (applied frame
    by frame)."""
    arrays = _record_arrays(record)
    if arrays is None:
        return None
    offset, scale, matrix = arrays
    shifted = values - offset
    return _mat_vec_rows(matrix, shifted if scale is None else shifted * scale)


_ARRAYS: dict[int, tuple[object, tuple[FloatArray, FloatArray | None, FloatArray] | None]] = {}
"""``_record_arrays`` by the record's id, with the record (kept alive, so its id is not
reused while it is here; records are frozen, so the arrays never go stale)."""


def _record_arrays(record: object) -> tuple[FloatArray, FloatArray | None, FloatArray] | None:
    """A calibration record's offset, scale (None: none) and matrix as arrays, made once per
    record (every block of its stream needs them)."""
    hit = _ARRAYS.get(id(record))
    if hit is not None and hit[0] is record:
        return hit[1]
    arrays: tuple[FloatArray, FloatArray | None, FloatArray] | None = None
    if isinstance(record, AccelCalibration | GyroCalibration):
        o = record.offset_m_s2 if isinstance(record, AccelCalibration) \
            else record.offset_rad_s
        arrays = (_vec(o), _vec(record.scale), _vec(record.misalignment))
    elif isinstance(record, MagCalibration):
        arrays = (_vec(record.hard_iron_ut), None, _vec(record.soft_iron))
    elif isinstance(record, VectorCalibration):
        arrays = (_vec(record.offset), None, _vec(record.matrix))
    if len(_ARRAYS) >= 64:  # records replaced in flight (learners): forget the old ones
        _ARRAYS.clear()
    _ARRAYS[id(record)] = (record, arrays)
    return arrays


def _vec(v: Sequence[float] | Sequence[Sequence[float]]) -> FloatArray:
    return np.asarray(v, dtype=np.float64)


def _mat_vec_rows(m: Sequence[Sequence[float]] | FloatArray, v: FloatArray,
                  start: float | None = None) -> FloatArray:
    """``m @ v`` for every row of ``v`` (n, 3), each component summed left to right as the
    calibration's plain-float ``_mat_vec`` sums it (from ``start`` first, as ``_rotate``
    sums from +0.0): the nine products of each row in one call, then two or three sums,
    whatever n (a few numpy calls a block, not one per component)."""
    matrix = m if type(m) is np.ndarray else np.asarray(m, dtype=np.float64)
    products: FloatArray = v[:, None, :] * matrix  # (n, 3, 3): row i of m times each frame
    first = products[:, :, 0] if start is None else start + products[:, :, 0]
    out: FloatArray = first + products[:, :, 1] + products[:, :, 2]
    return out


def _calibrated(block: Block, record: _Correction | None) -> FloatArray:
    """The block's values with ``record`` applied to its valid frames (flagged frames stay
    raw, as :func:`calibrate_to_body` leaves them)."""
    values = block.values
    if record is None:
        return values
    flags = block.flags
    if block.flagged:
        valid = flags == 0
        if not bool(valid.any()):
            return values
    else:
        valid = None  # the common case: every frame calibrated
    corrected = _corrected(record, values)
    if corrected is None:
        corrected = np.array([record.apply((v[0], v[1], v[2])) for v in values.tolist()])
    return corrected if valid is None else np.where(valid[:, None], corrected, values)


def calibrate_block(block: Block, calibration: DeviceCalibration | None,
                    chip_to_body: list[list[float]], *,
                    matrix: FloatArray | None = None) -> Block:
    """:func:`calibrate_to_body` for every frame of ``block`` at once (valid frames
    calibrated, every frame rotated), the same floats: each rotated component is summed
    from +0.0 left to right as :func:`_rotate` sums it. One frame built from a sample goes
    through :func:`calibrate_to_body` itself. ``matrix``: ``chip_to_body`` as a float64
    array already (made once per device rather than once per block)."""
    if not issubclass(block.kind, VectorSample):
        return block
    if len(block) == 1 and block.has_rows:
        row = block.samples()[0]
        out = calibrate_to_body(row, calibration if row.valid else None, chip_to_body)
        return block if out is row else Block.from_samples([out], block.spec)
    record = None if calibration is None else \
        _record_of(block.kind, block.quantity.name, calibration)
    if block.frame is not Frame.BODY_NED and not block.flagged:
        quick = _permuted(block.values, record, chip_to_body if matrix is None else matrix)
        if quick is not None:
            return block.with_values(quick, Frame.BODY_NED)
    values = _calibrated(block, record)
    if block.frame is Frame.BODY_NED:
        return block if values is block.values else block.with_values(values, block.frame)
    # each element the same products summed from +0.0 left to right as _rotate sums them
    return block.with_values(_mat_vec_rows(chip_to_body if matrix is None else matrix,
                                           values, 0.0), Frame.BODY_NED)


def _permuted(values: FloatArray, record: _Correction | None,
              chip_to_body: Sequence[Sequence[float]] | FloatArray) -> FloatArray | None:
    """What :func:`_calibrated` and the rotation give for a block of unflagged frames when
    the mount is a signed permutation of the axes and the record's matrix (if any) is the
    identity, in three or four numpy calls instead of a dozen; None when that does not
    hold or a value is not finite (the general path then).

    The same floats: with finite values, the record's identity product leaves each
    component as it is but for the sign of a zero (``x + y * 0.0 + z * 0.0``); the
    rotation's sum from +0.0 of one product by +-1 and two by zero is that product, a
    zero made +0.0 (``+0.0 + -0.0`` is +0.0), whatever the zero's sign was. So the result
    is ``sign * calibrated[axis] + 0.0``, exactly."""
    mount = _signed_permutation(chip_to_body)
    if mount is None:
        return None
    axes, signs = mount
    if record is not None:
        plain = _plain_record(record)
        if plain is None:
            return None
        offset, scale = plain
        values = values - offset
        if scale is not None:
            values = values * scale
    out: FloatArray = values[:, axes]  # a new array: fancy indexing copies
    np.multiply(out, signs, out=out)
    np.add(out, 0.0, out=out)
    # a NaN or an infinity anywhere makes the sum one too (the general path then; the
    # general product also mixes the zero terms' NaNs, 0.0 * inf, into the other axes)
    if not math.isfinite(_SUM(out, axis=None)):
        return None
    return out


_SUM = np.add.reduce


def _signed_permutation(m: Sequence[Sequence[float]] | FloatArray
                        ) -> tuple[IntArray, FloatArray] | None:
    """``m``'s rows as (the axis each takes, its sign +-1.0) when each row holds one +-1
    and two zeros and no two rows take one axis; None otherwise. Kept per matrix object
    (a device's mount is made once)."""
    hit = _PERMUTATIONS.get(id(m))
    if hit is not None and hit[0] is m:
        return hit[1]
    rows = np.asarray(m, dtype=np.float64)
    found: tuple[IntArray, FloatArray] | None = None
    if rows.shape == (3, 3):
        axes = np.argmax(np.abs(rows), axis=1)
        picked = rows[np.arange(3), axes]
        rest = rows.copy()
        rest[np.arange(3), axes] = 0.0
        if sorted(axes.tolist()) == [0, 1, 2] and bool(np.all(np.abs(picked) == 1.0)) \
                and not bool(np.any(rest)):
            found = (axes.astype(np.int64), picked.copy())
    if len(_PERMUTATIONS) >= 64:
        _PERMUTATIONS.clear()
    _PERMUTATIONS[id(m)] = (m, found)
    return found


_PERMUTATIONS: dict[int, tuple[object, tuple[IntArray, FloatArray] | None]] = {}
"""``_signed_permutation`` by the matrix's id, with the matrix (kept alive, so its id is
not reused while it is here)."""


def _plain_record(record: object) -> tuple[FloatArray, FloatArray | None] | None:
    """A record whose matrix is the identity, as its offset and its scale (None: none, or
    every factor 1.0, which changes no float); None for any other record. Kept per record,
    as :func:`_record_arrays`."""
    hit = _PLAIN.get(id(record))
    if hit is not None and hit[0] is record:
        return hit[1]
    arrays = _record_arrays(record)
    plain: tuple[FloatArray, FloatArray | None] | None = None
    if arrays is not None and arrays[2].shape == (3, 3) \
            and bool(np.array_equal(arrays[2], np.eye(3))):
        offset, scale, _ = arrays
        unit = scale is None or bool(np.all(scale == 1.0))
        plain = (offset, None if unit else scale)
    if len(_PLAIN) >= 64:  # records replaced in flight (learners): forget the old ones
        _PLAIN.clear()
    _PLAIN[id(record)] = (record, plain)
    return plain


_PLAIN: dict[int, tuple[object, tuple[FloatArray, FloatArray | None] | None]] = {}


def _record_of(kind: type[Sample], quantity: str, calibration: DeviceCalibration
               ) -> _Correction | None:
    if issubclass(kind, AccelSample):
        return calibration.accel
    if issubclass(kind, GyroSample):
        return calibration.gyro
    if issubclass(kind, MagSample):
        return calibration.mag
    return calibration.record_for(quantity)
