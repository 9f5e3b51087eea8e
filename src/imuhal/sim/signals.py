"""Smooth scalar profiles of time with exact first and second derivatives.

A :class:`Signal` is the building block of every trajectory: an angle (rad), a speed (m/s) or
a position (m) as a function of time (s). It is built from

* a base value and rate,
* a chronological list of non-overlapping *transitions*: value steps (the rate rises and falls
  as ``1 - cos``, so value, rate and acceleration stay continuous) and rate steps (the rate
  changes along a raised cosine, so rate and acceleration stay continuous),
* windowed sinusoids (single tones or seeded sums of tones for turbulence), faded in and out
  with a quintic smootherstep envelope.

Evaluation ``signal(t) -> (value, d/dt, d2/dt2)`` uses plain floats and a bisection over
precompiled transition starts, because it runs at every sensor poll.
"""

from __future__ import annotations

import math
from bisect import bisect_right
from dataclasses import dataclass, field
from math import cos, sin

import numpy as np

_TWO_PI = 2.0 * math.pi

STEP = 0
"""Transition kind: the value moves by ``delta`` (rate zero at both ends)."""
RATE = 1
"""Transition kind: the rate changes by ``delta`` (raised-cosine ramp)."""


@dataclass(frozen=True, slots=True)
class _Transition:
    t0: float
    duration: float
    kind: int
    delta: float
    v_start: float
    r_start: float
    v_end: float
    r_end: float


@dataclass(frozen=True, slots=True)
class _Tones:
    """A group of sinusoids sharing one fade-in/fade-out window."""

    t_on: float
    t_off: float
    ramp_s: float
    amplitudes: tuple[float, ...]
    omegas: tuple[float, ...]
    phases: tuple[float, ...]
    terms: tuple[tuple[float, float, float, float], ...] = field(init=False)
    """(amplitude, omega, phase, omega^2) of each tone, gathered once for the evaluation."""

    def __post_init__(self) -> None:
        object.__setattr__(self, "terms", tuple(
            (a, w, ph, w * w)
            for a, w, ph in zip(self.amplitudes, self.omegas, self.phases, strict=True)))


def _smootherstep(x: float) -> tuple[float, float, float]:
    """Quintic 0 -> 1 ramp on x in [0, 1] and its first two derivatives in x."""
    if x <= 0.0:
        return 0.0, 0.0, 0.0
    if x >= 1.0:
        return 1.0, 0.0, 0.0
    return (x * x * x * (10.0 - 15.0 * x + 6.0 * x * x),
            30.0 * x * x * (1.0 - x) * (1.0 - x),
            60.0 * x * (1.0 - x) * (1.0 - 2.0 * x))


def _smootherstep_many(x: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """:func:`_smootherstep` at every ``x`` (the same operations)."""
    inside = (x > 0.0) & (x < 1.0)
    e = np.where(inside, x * x * x * (10.0 - 15.0 * x + 6.0 * x * x),
                 np.where(x >= 1.0, 1.0, 0.0))
    e1 = np.where(inside, 30.0 * x * x * (1.0 - x) * (1.0 - x), 0.0)
    e2 = np.where(inside, 60.0 * x * (1.0 - x) * (1.0 - 2.0 * x), 0.0)
    return e, e1, e2


class Signal:
    """A scalar function of time built from transitions and windowed tones.

    Builder methods return ``self`` so profiles read like a schedule::

        yaw = Signal(0.0).rate_to(10.0, 2.0, 0.3).rate_to(40.0, 2.0, 0.0)

    Transitions must be added in time order and must not overlap (the builder checks it);
    tones may overlap anything.
    """

    __slots__ = ("_end_t", "_end_v", "_r0", "_starts", "_tones", "_transitions", "_v0")

    def __init__(self, value: float = 0.0, rate: float = 0.0) -> None:
        self._v0 = float(value)
        self._r0 = float(rate)
        self._transitions: list[_Transition] = []
        self._starts: list[float] = []
        self._tones: list[_Tones] = []
        self._end_t = -math.inf
        self._end_v = self._v0

    # ----------------------------------------------------------------------------- building
    def base_state(self, t_s: float) -> tuple[float, float]:
        """(value, rate) of the transitions alone (no tones) at ``t_s``."""
        v, r, _ = self._ramps(t_s)
        return v, r

    def _add(self, t0: float, duration: float, kind: int, delta: float) -> Signal:
        if duration <= 0 or not math.isfinite(duration):
            raise ValueError(f"a transition needs a positive duration, got {duration}")
        if t0 < self._end_t - 1e-12:
            raise ValueError(
                f"transition at t={t0} s starts before the previous one ends "
                f"(t={self._end_t} s): add transitions in time order, without overlap"
            )
        v_start, r_start = self.base_state(t0)
        if kind == STEP:
            v_end, r_end = v_start + r_start * duration + delta, r_start
        else:
            v_end, r_end = v_start + r_start * duration + delta * duration / 2.0, r_start + delta
        self._transitions.append(
            _Transition(t0, duration, kind, delta, v_start, r_start, v_end, r_end))
        self._starts.append(t0)
        self._end_t = t0 + duration
        return self

    def step(self, t0: float, duration: float, delta: float) -> Signal:
        """Move the value by ``delta`` over ``duration`` s from ``t0``; rate 0 at both ends
        (on top of any constant rate already present)."""
        return self._add(t0, duration, STEP, delta)

    def step_to(self, t0: float, duration: float, value: float) -> Signal:
        """Move to ``value`` by ``t0 + duration`` (assumes zero base rate at ``t0``)."""
        v, r = self.base_state(t0)
        return self._add(t0, duration, STEP, value - v - r * duration)

    def rate_step(self, t0: float, duration: float, delta_rate: float) -> Signal:
        """Change the rate by ``delta_rate`` along a raised cosine lasting ``duration``."""
        return self._add(t0, duration, RATE, delta_rate)

    def rate_to(self, t0: float, duration: float, rate: float) -> Signal:
        """Change the rate to ``rate`` along a raised cosine lasting ``duration``."""
        return self._add(t0, duration, RATE, rate - self.base_state(t0)[1])

    def sweep(self, t0: float, duration: float, delta: float, ramp_s: float) -> Signal:
        """Move the value by ``delta`` with a trapezoidal rate: ramp up over ``ramp_s``,
        hold a constant rate, ramp down over ``ramp_s``; done at ``t0 + duration``.

        Gentler than :meth:`step` for large moves (loops, rolls, constant-rate turns): the
        peak rate is ``delta / (duration - ramp_s)`` instead of ``2 delta / duration``.
        """
        if not 0 < 2 * ramp_s <= duration:
            raise ValueError(f"sweep needs 0 < 2*ramp_s <= duration (ramp {ramp_s}, "
                             f"duration {duration})")
        rate = delta / (duration - ramp_s)
        r0 = self.base_state(t0)[1]
        self.rate_step(t0, ramp_s, rate)
        return self.rate_to(t0 + duration - ramp_s, ramp_s, r0)

    def oscillate(self, amplitude: float, period_s: float, *, t_on: float = 0.0,
                  t_off: float = math.inf, ramp_s: float = 1.0,
                  phase_rad: float = 0.0) -> Signal:
        """Add ``amplitude * sin(2 pi t / period_s + phase_rad)``, faded in from ``t_on``
        and out before ``t_off`` over ``ramp_s`` seconds each."""
        return self._tones_add(t_on, t_off, ramp_s, (amplitude,), (_TWO_PI / period_s,),
                               (phase_rad,))

    def turbulence(self, rng: np.random.Generator, rms: float, *, f_min_hz: float,
                   f_max_hz: float, tones: int = 8, t_on: float = 0.0,
                   t_off: float = math.inf, ramp_s: float = 2.0,
                   derivative: int = 0) -> Signal:
        """Add a seeded, band-limited random wiggle: ``tones`` sinusoids with log-uniform
        frequencies in [f_min, f_max] and random phases, whose ``derivative``-th time
        derivative (0: the value itself, 1: its rate) has total RMS ``rms``.

        Deterministic for a given generator state; smooth, so its derivatives are exact.
        """
        if tones <= 0 or rms == 0.0:
            return self
        freqs = np.exp(rng.uniform(math.log(f_min_hz), math.log(f_max_hz), tones))
        phases = rng.uniform(0.0, _TWO_PI, tones)
        weights = rng.uniform(0.5, 1.5, tones)
        amps = weights * rms * math.sqrt(2.0) / math.sqrt(float(np.sum(weights**2)))
        amps = amps / (_TWO_PI * freqs) ** derivative
        return self._tones_add(t_on, t_off, ramp_s, tuple(float(a) for a in amps),
                               tuple(float(_TWO_PI * f) for f in freqs),
                               tuple(float(p) for p in phases))

    def _tones_add(self, t_on: float, t_off: float, ramp_s: float,
                   amps: tuple[float, ...], omegas: tuple[float, ...],
                   phases: tuple[float, ...]) -> Signal:
        if ramp_s <= 0:
            raise ValueError("ramp_s must be positive")
        if t_off - t_on < 2 * ramp_s:
            raise ValueError(f"tone window [{t_on}, {t_off}] is shorter than two ramps")
        self._tones.append(_Tones(t_on, t_off, ramp_s, amps, omegas, phases))
        return self

    # ----------------------------------------------------------------------------- evaluation
    def _ramps(self, t: float) -> tuple[float, float, float]:
        i = bisect_right(self._starts, t) - 1
        if i < 0:
            return self._v0 + self._r0 * t, self._r0, 0.0
        tr = self._transitions[i]
        tau = t - tr.t0
        if tau >= tr.duration:
            return tr.v_end + tr.r_end * (tau - tr.duration), tr.r_end, 0.0
        d, dur = tr.delta, tr.duration
        s = tau / dur
        v = tr.v_start + tr.r_start * tau
        if tr.kind == STEP:
            ang = _TWO_PI * s
            return (v + d * (s - math.sin(ang) / _TWO_PI),
                    tr.r_start + d / dur * (1.0 - math.cos(ang)),
                    d * _TWO_PI / (dur * dur) * math.sin(ang))
        ang = math.pi * s
        return (v + 0.5 * d * (tau - dur / math.pi * math.sin(ang)),
                tr.r_start + 0.5 * d * (1.0 - math.cos(ang)),
                0.5 * d * math.pi / dur * math.sin(ang))

    def _ramp_value(self, t: float) -> float:
        """The value of :meth:`_ramps` alone (the same operations)."""
        i = bisect_right(self._starts, t) - 1
        if i < 0:
            return self._v0 + self._r0 * t
        tr = self._transitions[i]
        tau = t - tr.t0
        if tau >= tr.duration:
            return tr.v_end + tr.r_end * (tau - tr.duration)
        d, dur = tr.delta, tr.duration
        s = tau / dur
        v = tr.v_start + tr.r_start * tau
        if tr.kind == STEP:
            return v + d * (s - math.sin(_TWO_PI * s) / _TWO_PI)
        return v + 0.5 * d * (tau - dur / math.pi * math.sin(math.pi * s))

    def value(self, t: float) -> float:
        """The value at time ``t`` (s) alone: ``self(t)[0]``, the same float, for less (a
        position needs no derivatives)."""
        v = self._ramp_value(t)
        for g in self._tones:
            if t <= g.t_on or t >= g.t_off:
                continue
            ramp = g.ramp_s
            if t < g.t_on + ramp:
                e = _smootherstep((t - g.t_on) / ramp)[0]
            elif t > g.t_off - ramp:
                e = _smootherstep((g.t_off - t) / ramp)[0]
            else:  # full amplitude: as in __call__, the value's terms alone
                for amp, w, ph, _ in g.terms:
                    v += amp * sin(w * t + ph)
                continue
            for amp, w, ph, _ in g.terms:
                v += amp * e * math.sin(w * t + ph)
        return v

    def value_rate(self, t: float) -> tuple[float, float]:
        """(value, first derivative) at time ``t`` (s): ``self(t)[:2]``, the same floats,
        without the second derivative (an attitude angle needs its rate, not its
        acceleration)."""
        v, r, _ = self._ramps(t)
        for g in self._tones:
            if t <= g.t_on or t >= g.t_off:
                continue
            ramp = g.ramp_s
            if t < g.t_on + ramp:
                e, e1, _ = _smootherstep((t - g.t_on) / ramp)
                e1 = e1 / ramp
            elif t > g.t_off - ramp:
                e, e1, _ = _smootherstep((g.t_off - t) / ramp)
                e1 = -e1 / ramp
            else:  # full amplitude: as in __call__, without the acceleration's terms
                for amp, w, ph, _ in g.terms:
                    th = w * t + ph
                    v += amp * sin(th)
                    r += amp * (w * cos(th))
                continue
            for amp, w, ph, _ in g.terms:
                th = w * t + ph
                sn, cs = math.sin(th), math.cos(th)
                v += amp * e * sn
                r += amp * (e1 * sn + e * w * cs)
        return v, r

    def many(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(value, d/dt, d2/dt2)`` at every time of ``t`` (s, a float64 array) in three
        arrays: what :meth:`__call__` gives at each, by the same operations in the same order
        (so :meth:`value` and :meth:`value_rate` too, which share them), on numpy arrays.
        Only numpy's ``sin``/``cos`` may differ from ``math``'s, by an ulp or so."""
        t = np.asarray(t, dtype=float)
        v = self._v0 + self._r0 * t
        r = np.full_like(t, self._r0)
        a = np.zeros_like(t)
        if self._transitions:
            index = np.searchsorted(np.asarray(self._starts), t, side="right") - 1
            for i in np.unique(index[index >= 0]).tolist():
                sel = index == i
                v[sel], r[sel], a[sel] = self._transition_many(self._transitions[i], t[sel])
        for g in self._tones:
            self._tones_many(g, t, v, r, a)
        return v, r, a

    @staticmethod
    def _transition_many(tr: _Transition, t: np.ndarray
                         ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """:meth:`_ramps` for times whose latest transition is ``tr``."""
        tau = t - tr.t0
        after = tau >= tr.duration
        d, dur = tr.delta, tr.duration
        s = tau / dur
        v = tr.v_start + tr.r_start * tau
        if tr.kind == STEP:
            ang = _TWO_PI * s
            sn = np.sin(ang)
            v = v + d * (s - sn / _TWO_PI)
            r = tr.r_start + d / dur * (1.0 - np.cos(ang))
            a = d * _TWO_PI / (dur * dur) * sn
        else:
            ang = math.pi * s
            sn = np.sin(ang)
            v = v + 0.5 * d * (tau - dur / math.pi * sn)
            r = tr.r_start + 0.5 * d * (1.0 - np.cos(ang))
            a = 0.5 * d * math.pi / dur * sn
        return (np.where(after, tr.v_end + tr.r_end * (tau - tr.duration), v),
                np.where(after, tr.r_end, r), np.where(after, 0.0, a))

    @staticmethod
    def _tones_many(g: _Tones, t: np.ndarray, v: np.ndarray, r: np.ndarray,
                    a: np.ndarray) -> None:
        """Add one group of tones to ``v``, ``r``, ``a`` in place, as :meth:`__call__`
        does: the full-amplitude terms written out, the ramps through the envelope."""
        ramp = g.ramp_s
        on = (t > g.t_on) & (t < g.t_off)
        rising = on & (t < g.t_on + ramp)
        falling = on & ~rising & (t > g.t_off - ramp)
        full = on & ~rising & ~falling
        if full.any():
            tf = t[full]
            vf, rf, af = v[full], r[full], a[full]
            for amp, w, ph, w2 in g.terms:
                th = w * tf + ph
                sn = np.sin(th)
                vf += amp * sn
                rf += amp * (w * np.cos(th))
                af -= amp * (w2 * sn)
            v[full], r[full], a[full] = vf, rf, af
        for sel, x_of, sign in ((rising, lambda u: (u - g.t_on) / ramp, 1.0),
                                (falling, lambda u: (g.t_off - u) / ramp, -1.0)):
            if not sel.any():
                continue
            ts = t[sel]
            e, e1, e2 = _smootherstep_many(x_of(ts))
            e1, e2 = sign * e1 / ramp, e2 / (ramp * ramp)
            vs, rs, as_ = v[sel], r[sel], a[sel]
            for amp, w, ph, _ in g.terms:
                th = w * ts + ph
                sn, cs = np.sin(th), np.cos(th)
                vs += amp * e * sn
                rs += amp * (e1 * sn + e * w * cs)
                as_ += amp * (e2 * sn + 2.0 * e1 * w * cs - e * w * w * sn)
            v[sel], r[sel], a[sel] = vs, rs, as_

    def __call__(self, t: float) -> tuple[float, float, float]:
        """(value, first derivative, second derivative) at time ``t`` (s)."""
        # _ramps written out (the same operations): this runs for every signal at every
        # sensor poll, and most of a signal's time is spent past its last transition.
        i = bisect_right(self._starts, t) - 1
        if i < 0:
            v, r, a = self._v0 + self._r0 * t, self._r0, 0.0
        else:
            tr = self._transitions[i]
            tau = t - tr.t0
            if tau >= tr.duration:
                v, r, a = tr.v_end + tr.r_end * (tau - tr.duration), tr.r_end, 0.0
            else:
                v, r, a = self._ramps(t)
        if not self._tones:
            return v, r, a
        for g in self._tones:
            if t <= g.t_on or t >= g.t_off:
                continue
            ramp = g.ramp_s
            if t < g.t_on + ramp:
                e, e1, e2 = _smootherstep((t - g.t_on) / ramp)
                e1, e2 = e1 / ramp, e2 / (ramp * ramp)
            elif t > g.t_off - ramp:
                e, e1, e2 = _smootherstep((g.t_off - t) / ramp)
                e1, e2 = -e1 / ramp, e2 / (ramp * ramp)
            else:
                # Full amplitude, where a run spends nearly all its time: the loop below
                # with e = 1 and e1 = e2 = 0 written out, which gives the same floats (the
                # dropped terms are exact zeros) at about half the cost.
                for amp, w, ph, w2 in g.terms:
                    th = w * t + ph
                    sn = sin(th)
                    v += amp * sn
                    r += amp * (w * cos(th))
                    a -= amp * (w2 * sn)
                continue
            for amp, w, ph, _ in g.terms:
                th = w * t + ph
                sn, cs = math.sin(th), math.cos(th)
                v += amp * e * sn
                r += amp * (e1 * sn + e * w * cs)
                a += amp * (e2 * sn + 2.0 * e1 * w * cs - e * w * w * sn)
        return v, r, a
