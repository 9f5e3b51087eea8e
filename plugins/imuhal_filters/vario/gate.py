"""The altitude innovation gate both variometers share (``baro-vario``, ``vario-kf3``).

An altitude further than ``sigma`` standard deviations of the innovation (the square root of
the filter's altitude variance plus the measurement's) from the prediction is not fused
(counted ``gated``): one wild but in-range pressure, valid by design (docs/reliability.md),
must not throw the climb rate. The gate never closes within ``min_m``. Altitudes rejected
without a break for ``reacquire_s`` are a real change of level (a QNH change, a climb faster
than the model follows): the filter re-acquires it (``reacquire``, counted ``reacquired``).
Each filter passes its own variances (in its own units, ``units_per_m`` to the metre) and
its own way of re-acquiring.
"""

from __future__ import annotations

import math
from collections.abc import Callable


class InnovationGate:
    """One filter's gate and its rejected-since timer (see the module docstring)."""

    __slots__ = ("min_m", "reacquire_s", "rejected_since_ns", "sigma")

    def __init__(self, sigma: float | None, min_m: float, reacquire_s: float) -> None:
        self.sigma = sigma
        """Standard deviations of the innovation that close the gate (None: no gate)."""
        self.min_m = min_m
        self.reacquire_s = reacquire_s
        self.rejected_since_ns: int | None = None
        """When the current run of rejected altitudes began (None: the last was fused)."""

    def accept(self, t_ns: int, innovation_m: float, state_variance: float,
               measurement_variance: float, units_per_m: float,
               reacquire: Callable[[], None], counts: dict[str, int]) -> bool:
        """False (counted ``gated``) to skip this altitude's update. ``state_variance`` is the
        filter's altitude variance and ``measurement_variance`` the altitude measurement's,
        both in the filter's units squared (``units_per_m`` of them to the metre)."""
        k = self.sigma
        if k is None:
            return True
        sigma_m = math.sqrt(max(state_variance, 0.0) + measurement_variance) / units_per_m
        if abs(innovation_m) <= max(k * sigma_m, self.min_m):
            self.rejected_since_ns = None
            return True
        if self.rejected_since_ns is None:
            self.rejected_since_ns = t_ns
        if (t_ns - self.rejected_since_ns) / 1e9 < self.reacquire_s:
            counts["gated"] += 1
            return False
        counts["reacquired"] += 1
        self.rejected_since_ns = None
        reacquire()
        return True
