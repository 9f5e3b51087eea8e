"""The accelerometer filter of the "decoupled" estimator (VQF's choice of low-pass)."""

from __future__ import annotations

import math


class ButterworthLowPass:
    """The second-order Butterworth low-pass of cut-off sqrt(2) / (2 pi tau) on an n-vector
    (VQF's choice: mean delay tau, 40 dB/decade above the cut-off, and about twice the
    attenuation of two cascaded first-order stages of the same delay at hand motion's
    0.5 Hz), simulated exactly for any step length with the input held over the step, so a
    step may be shortened per sample (a step of zero holds the state). Starts at rest at its
    first input."""

    def __init__(self, tau_s: float) -> None:
        # poles at sigma (-1 +- i): sigma = omega_c / sqrt(2) = 1 / tau
        self.sigma = 1.0 / tau_s
        self.state: list[float] | None = None
        self._dt = -1.0
        self._m = (1.0, 0.0, 0.0, 1.0)

    def _matrix(self, dt: float) -> tuple[float, float, float, float]:
        """(a, b, c, d): [z, z'] -> [a z + b z', c z + d z'] for the error z = y - u."""
        if dt != self._dt:
            s = self.sigma
            e = math.exp(-s * dt)
            c, si = math.cos(s * dt), math.sin(s * dt)
            self._m = (e * (c + si), e * si / s, -2.0 * s * e * si, e * (c - si))
            self._dt = dt
        return self._m

    def step(self, x: tuple[float, ...], dt: float) -> tuple[float, ...]:
        st = self.state
        n = len(x)
        if st is None:
            st = self.state = [*x, *([0.0] * n)]
        a, b, c, d = self._matrix(dt)
        for i in range(n):
            z, zd = st[i] - x[i], st[n + i]
            st[i] = x[i] + a * z + b * zd
            st[n + i] = c * z + d * zd
        return tuple(st[:n])
