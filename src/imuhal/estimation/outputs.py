"""What estimators produce. Units and frames are in the names."""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field, fields
from enum import IntFlag
from typing import Any

import numpy as np

from imuhal.core.frames import FloatArray, euler_deg_from_quat
from imuhal.core.samples import Vec3, slot_setter


@dataclass(frozen=True, slots=True, kw_only=True)
class Estimate:
    t_ns: int
    source: str
    """The name of the estimator instance (its key in the profile)."""
    diagnostics: dict[str, Any] = field(default_factory=dict)


@dataclass(frozen=True, slots=True, kw_only=True)
class AttitudeEstimate(Estimate):
    """Orientation as a unit quaternion (w, x, y, z) rotating body -> NED."""

    q_body_to_ned: tuple[float, float, float, float]
    linear_accel_ned_m_s2: Vec3 | None = None
    """Gravity-compensated acceleration in NED (m/s^2), when the estimator had an accel sample."""

    @property
    def roll_pitch_yaw_deg(self) -> tuple[float, float, float]:
        """Seed conventions: roll right +, pitch up +, yaw [-180, 180] clockwise from north."""
        return euler_deg_from_quat(self.q_body_to_ned)

    @classmethod
    def build(cls, t_ns: int, source: str, q_body_to_ned: tuple[float, float, float, float],
              linear_accel_ned_m_s2: Vec3 | None, diagnostics: dict[str, Any]
              ) -> AttitudeEstimate:
        """The same estimate as the keyword constructor, built faster (an AHRS makes one
        per gyro sample): the fields are set through their slots, where the generated
        ``__init__`` of a frozen class goes through ``object.__setattr__`` per field."""
        e = _new(cls)
        _set_t_ns(e, t_ns)
        _set_source(e, source)
        _set_diagnostics(e, diagnostics)
        _set_q(e, q_body_to_ned)
        _set_linear_accel(e, linear_accel_ned_m_s2)
        return e


@dataclass(frozen=True, slots=True, kw_only=True)
class VerticalEstimate(Estimate):
    """Altitude above the pressure reference (m, up +) and climb rate (m/s, up +)."""

    altitude_m: float
    climb_m_s: float
    accel_bias_m_s2: float | None = None

    @classmethod
    def build(cls, t_ns: int, source: str, altitude_m: float, climb_m_s: float,
              accel_bias_m_s2: float | None, diagnostics: dict[str, Any]
              ) -> VerticalEstimate:
        """The same estimate as the keyword constructor, built through its slots (a
        variometer makes one per pressure sample), as ``AttitudeEstimate.build``."""
        e = _new(cls)
        _set_t_ns(e, t_ns)
        _set_source(e, source)
        _set_diagnostics(e, diagnostics)
        _set_altitude(e, altitude_m)
        _set_climb(e, climb_m_s)
        _set_bias(e, accel_bias_m_s2)
        return e


class EstimateFlag(IntFlag):
    """Why the pipeline refused an estimate (docs/reliability.md, "Estimates carry
    validity"). An estimate with any of these never reaches a sink as a number: the sinks
    get a :class:`RejectedEstimate` in its place."""

    NOT_FINITE = 1
    """A value is NaN or infinite."""
    NOT_NORMALISABLE = 2
    """An attitude quaternion whose norm is zero (or too small to divide by): no rotation."""
    UNSETTLED = 4
    """Set by the estimator itself, which withholds its value: it rejected most of its
    recent inputs (a variometer whose innovation gate refused most altitudes of the last
    second), so the value may be far off and it has no better one. Not a failure."""


_MIN_QUAT_NORM_SQ = 1e-12
"""A quaternion whose squared norm is below this has no direction left to normalise."""


@dataclass(frozen=True, slots=True, kw_only=True)
class RejectedEstimate(Estimate):
    """What the sinks and the downstream estimators get instead of an estimate that is not
    finite or not normalisable (the pipeline makes it), or that its estimator withholds
    (``UNSETTLED``: the estimator makes it): when, which estimator instance (``source``) and
    which plugin estimator (``estimator``) made it, its kind (``"attitude"``, ``"vertical"``
    or the class name) and why (``flags``). It carries no value on purpose."""

    kind: str
    flags: EstimateFlag
    estimator: str = ""


class AttitudeBlock:
    """The attitude estimates one estimator made of one fusion step's frames (an AHRS's
    compiled block step over a FIFO read), as columns: the estimates stay arrays until
    something asks for them one by one (:meth:`rows`: the ``AttitudeEstimate`` objects,
    diagnostics included, that the frames one by one would have made, the same floats).
    The live pipeline hands such a block to the estimators downstream whole
    (``Estimator.update_estimate_block``) and to a consumer of ``Pipeline.blocks()``;
    ``Pipeline.events()``, sinks and every other consumer get its rows. Not an
    :class:`Estimate` itself: nothing takes it for one estimate by mistake."""

    __slots__ = ("_diagnostics", "_rows", "linear_accel_ned_m_s2", "q_body_to_ned",
                 "source", "t_ns")

    def __init__(self, source: str, t_ns: np.ndarray, q_body_to_ned: FloatArray,
                 linear_accel_ned_m_s2: FloatArray | None,
                 diagnostics: Callable[[], list[dict[str, Any]]]) -> None:
        self.source = source
        """The estimator instance that made the estimates (``Estimate.source``)."""
        self.t_ns = t_ns
        """Each estimate's time stamp (int64 ns), oldest first."""
        self.q_body_to_ned = q_body_to_ned
        """(n, 4): each estimate's unit quaternion (w, x, y, z) rotating body -> NED."""
        self.linear_accel_ned_m_s2 = linear_accel_ned_m_s2
        """(n, 3): each estimate's gravity-compensated acceleration in NED (m/s^2), or
        None when no estimate has one."""
        self._diagnostics = diagnostics
        self._rows: list[AttitudeEstimate] | None = None

    def __len__(self) -> int:
        return len(self.t_ns)

    def __repr__(self) -> str:
        return f"AttitudeBlock(source={self.source!r}, rows={len(self)})"

    def rows(self) -> list[AttitudeEstimate]:
        """The estimates one by one (built once, on the first call)."""
        rows = self._rows
        if rows is None:
            build, source = AttitudeEstimate.build, self.source
            lin = self.linear_accel_ned_m_s2
            lins: list[Any] = [None] * len(self) if lin is None else \
                [(x, y, z) for x, y, z in lin.tolist()]
            rows = self._rows = [
                build(t, source, (w, x, y, z), a, d)
                for t, (w, x, y, z), a, d in zip(
                    self.t_ns.tolist(), self.q_body_to_ned.tolist(), lins,
                    self._diagnostics(), strict=True)]
        return rows

    def all_usable(self) -> bool:
        """True when :func:`estimate_flags` passes every row (finite quaternions of a norm
        above zero, finite accelerations), on each row's floats with the same sums in the
        same order. (On plain floats: for the few rows of a FIFO read, a loop costs less
        than the numpy calls over columns.)"""
        for w, x, y, z in self.q_body_to_ned.tolist():
            # one comparison catches NaN, infinity and a zero norm alike (NaN compares False)
            if not _MIN_QUAT_NORM_SQ < w * w + x * x + y * y + z * z < math.inf:
                return False
        lin = self.linear_accel_ned_m_s2
        if lin is not None:
            for a, b, c in lin.tolist():
                if not math.isfinite(a + b + c):
                    return False
        return True


def usable_blocks_kept(made: list[Any]) -> list[Any]:
    """``made`` with each AttitudeBlock that has a row the estimate check refuses
    (``AttitudeBlock.all_usable``) replaced by its rows, each then checked as one estimate;
    the others stay whole (``made`` itself when none is replaced)."""
    if len(made) == 1:  # the usual case (an AHRS's block step): no generator set up
        e = made[0]
        return made if type(e) is not AttitudeBlock or e.all_usable() else list(e.rows())
    if all(type(e) is not AttitudeBlock or e.all_usable() for e in made):
        return made
    out: list[Any] = []
    for e in made:
        if type(e) is AttitudeBlock and not e.all_usable():
            out += e.rows()
        else:
            out.append(e)
    return out


def rows_of(made: list[Any]) -> list[Any]:
    """``made`` (estimates and :class:`AttitudeBlock` s) with every block replaced by its
    rows, in place order: what a consumer of estimates one by one gets."""
    if not any(type(e) is AttitudeBlock for e in made):
        return made
    out: list[Any] = []
    for e in made:
        if type(e) is AttitudeBlock:
            out += e.rows()
        else:
            out.append(e)
    return out


def estimate_kind(estimate: Estimate) -> str:
    """The CSV ``kind`` of an estimate: ``attitude``, ``vertical`` or its class name."""
    if isinstance(estimate, RejectedEstimate):
        return estimate.kind
    if isinstance(estimate, AttitudeEstimate):
        return "attitude"
    if isinstance(estimate, VerticalEstimate):
        return "vertical"
    return type(estimate).__name__


_NO_FLAGS = EstimateFlag(0)
"""(the same object as ``EstimateFlag(0)``, without the enum's Python call per estimate)"""


def estimate_flags(estimate: Estimate) -> EstimateFlag:
    """What is wrong with ``estimate`` (0: nothing). Attitude: the quaternion and the linear
    acceleration finite, the quaternion's norm above zero; vertical: altitude, climb rate and
    bias finite; any other estimate: every float (and tuple of floats) field finite."""
    if isinstance(estimate, AttitudeEstimate):
        w, x, y, z = estimate.q_body_to_ned
        norm_sq = w * w + x * x + y * y + z * z
        acc = estimate.linear_accel_ned_m_s2
        # one comparison catches NaN, infinity and a zero norm alike (NaN compares False)
        if _MIN_QUAT_NORM_SQ < norm_sq < math.inf and (
                acc is None or math.isfinite(acc[0] + acc[1] + acc[2])):
            return _NO_FLAGS
        return _attitude_flags(estimate)
    if isinstance(estimate, VerticalEstimate):
        bias = estimate.accel_bias_m_s2
        total = estimate.altitude_m + estimate.climb_m_s + (0.0 if bias is None else bias)
        return _NO_FLAGS if math.isfinite(total) else EstimateFlag.NOT_FINITE
    if isinstance(estimate, RejectedEstimate):
        return estimate.flags
    return _generic_flags(estimate)


def refused_estimate(estimate: Estimate, flags: EstimateFlag, estimator: str
                     ) -> RejectedEstimate:
    """What takes the place of ``estimate``, refused for ``flags``, made by the plugin
    estimator ``estimator``: its time, source and kind, no value."""
    return RejectedEstimate(t_ns=estimate.t_ns, source=estimate.source,
                            kind=estimate_kind(estimate), flags=flags, estimator=estimator)


def checked_estimates(made: list[Estimate] | list[Any], estimator: str) -> int:
    """Replace, in place, every estimate of ``made`` that :func:`estimate_flags` refuses by
    its :func:`refused_estimate` (one its estimator withheld itself, a RejectedEstimate,
    stays, and so does an AttitudeBlock: :func:`usable_blocks_kept` first); returns how
    many were replaced. The offline chain's check, the live pipeline's
    (imuhal.pipeline.containment) without the counting and disabling."""
    replaced = 0
    for i, estimate in enumerate(made):
        if type(estimate) is RejectedEstimate or type(estimate) is AttitudeBlock:
            continue  # withheld by its estimator; a block every row of which passed
        flags = estimate_flags(estimate)
        if flags:
            made[i] = refused_estimate(estimate, flags, estimator)
            replaced += 1
    return replaced


def _attitude_flags(estimate: AttitudeEstimate) -> EstimateFlag:
    flags = EstimateFlag(0)
    values = list(estimate.q_body_to_ned) + list(estimate.linear_accel_ned_m_s2 or ())
    if not all(math.isfinite(v) for v in values):
        flags |= EstimateFlag.NOT_FINITE
    if not _MIN_QUAT_NORM_SQ < sum(v * v for v in estimate.q_body_to_ned) < math.inf:
        flags |= EstimateFlag.NOT_NORMALISABLE
    return flags


def _generic_flags(estimate: Estimate) -> EstimateFlag:
    """A third party's estimate: every float field, and every float in a tuple field."""
    for f in fields(estimate):
        if f.name in ("t_ns", "source", "diagnostics"):
            continue
        value = getattr(estimate, f.name)
        values = value if isinstance(value, tuple) else (value,)
        for v in values:
            if isinstance(v, float) and not math.isfinite(v):
                return EstimateFlag.NOT_FINITE
    return EstimateFlag(0)


# Slot setters for the ``build`` fast path (a frozen class forbids plain assignment).
_new = object.__new__
_set_t_ns = slot_setter(Estimate, "t_ns")
_set_source = slot_setter(Estimate, "source")
_set_diagnostics = slot_setter(Estimate, "diagnostics")
_set_q = slot_setter(AttitudeEstimate, "q_body_to_ned")
_set_linear_accel = slot_setter(AttitudeEstimate, "linear_accel_ned_m_s2")
_set_altitude = slot_setter(VerticalEstimate, "altitude_m")
_set_climb = slot_setter(VerticalEstimate, "climb_m_s")
_set_bias = slot_setter(VerticalEstimate, "accel_bias_m_s2")
