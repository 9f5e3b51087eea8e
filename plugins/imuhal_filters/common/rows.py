"""Row bookkeeping shared by every AHRS array path: which gyro frames step, with which inputs.

Before a filter step, ``update()`` and ``process()`` decide things that depend only on the
input and on a few held values, never on the filter: a gyro value beyond the full scale (or
not finite) means no step; an accelerometer beyond its full scale is dropped and counted; the
magnetometer must be finite; ``process()`` also holds the latest accepted accelerometer and
magnetometer sample, drops them when older than ``max_aux_age_s`` and takes the step length
from the gyro timestamps. This module makes those decisions for whole arrays at once, in
numpy (``update_rows`` for ``run_batch``, ``block_rows`` for a fusion step's blocks, live or
offline), and hands the kernels (compiled or not) only the rows that step, already resolved:
NaN rows in ``accel``/``mag`` mean "none this step". The counters and held values of the
estimator are updated exactly as the frames one by one would have left them.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from imuhal.core.blocks import Block
from imuhal.core.frames import FloatArray
from imuhal.core.samples import Quantity

if TYPE_CHECKING:
    from imuhal_filters.common.ahrs import AhrsEstimator

_NS = 1e-9


@dataclass(frozen=True)
class StepRows:
    """The rows that make one filter step each, with their inputs resolved (body NED)."""

    index: np.ndarray
    """(m,) position of each step's row in the input."""
    t_ns: np.ndarray | None
    """(m,) int64 gyro timestamps, or None (``update()`` semantics: no time stamps)."""
    gyro: FloatArray
    """(m, 3) rad/s."""
    accel: FloatArray
    """(m, 3) specific force m/s^2; a NaN row: no accelerometer this step."""
    mag: FloatArray
    """(m, 3) uT; a NaN row: no magnetometer this step."""
    dts: FloatArray
    """(m,) step lengths, s."""

    def __len__(self) -> int:
        return len(self.index)


def _all_within(values: FloatArray, full_scale: float) -> bool:
    """Every component of every row finite and within +-``full_scale`` (a finite scale:
    the estimators keep theirs at most the largest float), in two numpy calls: the common
    case's test before :func:`_within`'s per-row one (NaN and inf fail it)."""
    return len(values) == 0 or bool(np.abs(values).max() <= full_scale)


def _within(values: FloatArray, full_scale: float) -> np.ndarray:
    """Per row: every component finite and within +-full_scale (NaN fails)."""
    inside = np.abs(values) <= full_scale  # NaN fails; so does inf below an infinite scale
    if math.isinf(full_scale):
        inside &= np.isfinite(values)
    return inside.all(axis=1)  # type: ignore[return-value]  # numpy's stubs widen a reduction over an axis to a scalar


def _count(est: AhrsEstimator, channel: str, n: int) -> None:
    if n:  # the row-by-row path creates the key on the first rejection only
        beyond = est._counters["beyond_full_scale"]
        beyond[channel] = beyond.get(channel, 0) + n


def update_rows(est: AhrsEstimator, gyro: FloatArray, accel: FloatArray | None,
                mag: FloatArray | None, dts: FloatArray) -> StepRows:
    """``update()`` once per row (``run_batch``): a NaN row is "no sample"; gyro and accel
    beyond the full scale are counted (the accel only on rows whose gyro steps)."""
    n = gyro.shape[0]
    g_ok = _within(gyro, est._gyro_fs)
    bad = int(n - np.count_nonzero(g_ok))
    _count(est, Quantity.GYRO.value, bad)
    # the common case, every gyro row valid, takes the arrays as they are (no copies)
    idx: np.ndarray | slice = slice(0, n) if not bad else np.flatnonzero(g_ok)
    g, step_dts = gyro[idx], dts[idx]
    m_rows = len(g)
    a = m = None
    if accel is not None:
        a = accel[idx]
        ok = _within(a, est._accel_fs)
        if not ok.all():
            present = ~np.isnan(a).any(axis=1)
            _count(est, Quantity.ACCEL.value, int(np.count_nonzero(present & ~ok)))
            a = np.where(ok[:, None], a, np.nan)
    if mag is not None and est.uses_mag:
        m = mag[idx]
        ok = np.isfinite(m).all(axis=1)  # type: ignore[assignment]  # numpy's stubs widen a reduction over an axis to a scalar
        if not ok.all():
            m = np.where(ok[:, None], m, np.nan)
    return StepRows(np.arange(n)[idx], None, _c(g), _c(a, m_rows), _c(m, m_rows), _c(step_dts))


def _c(values: FloatArray | None, n: int = 0) -> FloatArray:
    """A writable C-ordered float array, as the kernels take it (a copy only when needed:
    a broadcast step length is read-only); None: n NaN rows."""
    if values is None:
        return np.full((n, 3), np.nan)
    return np.require(values, dtype=np.float64, requirements=["C", "W"])


def _step_lengths(est: AhrsEstimator, t_step: np.ndarray) -> FloatArray:
    """Each step's length from the previous stepped gyro time (nominal for the first step,
    when timestamps are off, and for gaps that are not in (0, max_dt_s])."""
    s = est.settings
    nominal = float(s.sample_period_s)
    m = len(t_step)
    if not s.dt_from_timestamps or m == 0:
        return np.full(m, nominal)
    prev = np.empty(m, dtype=np.int64)
    prev[1:] = t_step[:-1]
    first_known = est._last_gyro_t_ns is not None
    prev[0] = est._last_gyro_t_ns if first_known else t_step[0]  # type: ignore[assignment]  # first_known (tested on the same line) excludes None
    dt = (t_step - prev) * _NS
    bad = ~((dt > 0.0) & (dt <= s.max_dt_s))
    if not first_known:
        bad[0] = False  # nominal, not counted: there was no previous gyro sample
        dt[0] = nominal
    est._counters["dt_fallbacks"] += int(np.count_nonzero(bad))
    dt[bad] = nominal
    return dt  # type: ignore[return-value]  # numpy's stubs widen float64 arithmetic to floating[Any]


def block_rows(est: AhrsEstimator, gyro: Block, accel: Block | None, mag: Block | None
               ) -> StepRows:
    """``process()`` of the frames of one fusion step's blocks (valid, body NED; gyro,
    accelerometer and magnetometer, each of one stream) in fusion order: by time, and at
    one instant the accelerometer and magnetometer before the gyro. Each gyro frame within
    its full scale steps with the newest accepted accelerometer (and magnetometer) frame at
    or before its time, else the one the estimator holds, unless older than
    ``max_aux_age_s``. Counters, step lengths and held samples are left exactly as the
    frames one by one would leave them."""
    t = gyro.t_ns
    g = gyro.values
    if _all_within(g, est._gyro_fs):  # the common case: every frame steps, no copies
        idx = np.arange(len(t))
        t_step = t
        g_step = _c(g)
    else:
        g_ok = _within(g, est._gyro_fs)
        _count(est, Quantity.GYRO.value, int(len(t) - np.count_nonzero(g_ok)))
        idx = np.flatnonzero(g_ok)
        t_step = t[idx]
        g_step = np.ascontiguousarray(g[idx])
    accel_rows = _held_at(est, accel, t_step, "accel", est._accel_fs)
    # the magnetometer's scale is unbounded: only finite values are kept
    mag_rows = _held_at(est, mag, t_step, "mag", _MAX_FLOAT)
    dts = _step_lengths(est, t_step)
    if len(idx):
        est._last_gyro_t_ns = int(t_step[-1])
        last = g_step[-1]
        est._last_rate = (float(last[0]), float(last[1]), float(last[2]))
        held = accel_rows[-1]  # NaN: no fresh reading at the last step
        est._step_accel = None if held[0] != held[0] else (
            float(held[0]), float(held[1]), float(held[2]))
    return StepRows(idx, t_step, g_step, accel_rows, mag_rows, dts)


_MAX_FLOAT = float(np.finfo(np.float64).max)


def _held_at(est: AhrsEstimator, block: Block | None, t_step: np.ndarray, what: str,
             full_scale: float) -> FloatArray:
    """For each gyro step at ``t_step``, the ``what`` (accel or mag) frame it uses: the
    newest accepted frame of ``block`` at or before it, else the held one; NaN rows for none
    or too old (counted). Rejected frames are counted; the newest accepted one is held."""
    attr = "_accel_m_s2" if what == "accel" else "_mag_ut"
    held_v, held_t = getattr(est, attr), getattr(est, f"_{what}_t_ns")
    keep = what == "accel" or est.uses_mag  # process() holds no mag for a filter without
    m = len(t_step)
    if keep and block is not None and len(block) == m and np.array_equal(block.t_ns, t_step) \
            and bool((t_step[1:] > t_step[:-1]).all()):
        # the common case (a FIFO read, a log's chunk: a frame at every gyro frame's time,
        # each time once), when every frame is accepted: each step takes its own instant's,
        # never stale
        values = block.values
        if _all_within(values, full_scale):
            x, y, z = values[-1].tolist()
            setattr(est, attr, (x, y, z))
            setattr(est, f"_{what}_t_ns", int(t_step[-1]))
            return np.array(values, dtype=np.float64, order="C")
    out = np.full((m, 3), np.nan)
    t_src = np.zeros(m, dtype=np.int64)
    have = np.zeros(m, dtype=bool)
    if block is not None:
        ok = _within(block.values, full_scale)
        _count(est, Quantity.ACCEL.value if what == "accel" else Quantity.MAG.value,
               int(len(ok) - np.count_nonzero(ok)))
        if keep and bool(ok.any()):
            t_ok, v_ok = block.t_ns[ok], block.values[ok]
            src = np.searchsorted(t_ok, t_step, side="right") - 1
            have = src >= 0
            out[have] = v_ok[src[have]]
            t_src[have] = t_ok[src[have]]
            x, y, z = v_ok[-1].tolist()
            setattr(est, attr, (x, y, z))
            setattr(est, f"_{what}_t_ns", int(t_ok[-1]))
    if not keep:
        return out
    if held_v is not None and held_t is not None:
        before = ~have
        out[before] = held_v
        t_src[before] = held_t
        have = np.ones(m, dtype=bool)
    max_age = est.settings.max_aux_age_s
    if max_age is not None:
        stale = have & ((t_step - t_src) * _NS > max_age)
        est._counters[f"stale_{what}"] += int(np.count_nonzero(stale))
        have &= ~stale
    out[~have] = np.nan
    return out
