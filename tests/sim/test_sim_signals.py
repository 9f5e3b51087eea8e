"""Signal.value, the value-only evaluation of a position, gives the float of the full
evaluation, and that one the floats of the general formulas (every truth an emulated board
computes goes through them, and board runs are compared bit for bit)."""

from __future__ import annotations

import math

import numpy as np

from imuhal.sim.signals import Signal, _smootherstep


def _signal() -> Signal:
    """Transitions of both kinds, a single tone and a turbulence group whose windows
    open and close inside the sampled span."""
    sig = Signal(0.3, rate=-0.2).step(2.0, 3.0, 1.5).rate_to(6.0, 2.0, 0.7)
    sig.oscillate(0.4, 1.7, t_on=1.0, t_off=11.0, ramp_s=2.0, phase_rad=-0.8)
    return sig.turbulence(np.random.default_rng(3), 0.25, f_min_hz=0.1, f_max_hz=2.0,
                          tones=7, t_on=3.0, t_off=15.0, ramp_s=1.5, derivative=1)


def _by_the_formula(sig: Signal, t: float) -> tuple[float, float, float]:
    """Signal.__call__ written with the general (envelope) loop for every tone group, where
    the signal has a shortcut at full amplitude."""
    v, r, a = sig._ramps(t)
    for g in sig._tones:
        if t <= g.t_on or t >= g.t_off:
            continue
        ramp = g.ramp_s
        if t < g.t_on + ramp:
            e, e1, e2 = _smootherstep((t - g.t_on) / ramp)
            e1, e2 = e1 / ramp, e2 / (ramp * ramp)
        elif t > g.t_off - ramp:
            e, e1, e2 = _smootherstep((g.t_off - t) / ramp)
            e1, e2 = -e1 / ramp, e2 / (ramp * ramp)
        else:  # full amplitude: the envelope is 1, its derivatives 0
            e, e1, e2 = 1.0, 0.0, 0.0
        for amp, w, ph, _ in g.terms:
            th = w * t + ph
            sn, cs = math.sin(th), math.cos(th)
            v += amp * e * sn
            r += amp * (e1 * sn + e * w * cs)
            a += amp * (e2 * sn + 2.0 * e1 * w * cs - e * w * w * sn)
    return v, r, a


TIMES = [k * 0.0137 for k in range(1500)]  # 0 .. 20.5 s, every region of every window


def test_the_full_amplitude_shortcut_gives_the_floats_of_the_envelope_formula() -> None:
    sig = _signal()
    for t in TIMES:
        assert sig(t) == _by_the_formula(sig, t), t


def test_value_is_the_first_component_of_the_full_evaluation() -> None:
    sig = _signal()
    for t in TIMES:
        assert sig.value(t) == sig(t)[0], t


def test_value_rate_is_the_first_two_components_of_the_full_evaluation() -> None:
    sig = _signal()
    for t in TIMES:
        assert sig.value_rate(t) == sig(t)[:2], t
