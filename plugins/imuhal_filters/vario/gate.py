"""The altitude innovation gate both variometers share (``baro-vario``, ``vario-kf3``).

An altitude further than ``sigma`` standard deviations of the innovation (the square root of
the filter's altitude variance plus the measurement's) from the prediction is not fused
(counted ``gated``): one wild but in-range pressure, valid by design (docs/reliability.md),
must not throw the climb rate. The gate never closes within ``min_m``. Altitudes rejected
without a break for ``reacquire_s`` are a real change of level (a QNH change, a climb faster
than the model follows): the filter re-acquires it (``reacquire``, counted ``reacquired``).
Each filter passes its own variances (in its own units, ``units_per_m`` to the metre) and
its own way of re-acquiring.

A filter whose gate refused more than half the altitudes of the last ``UNSETTLED_WINDOW_S``
coasts on its model (and accelerometer) and may be far off: it has lost the barometer
(``unsettled``), and withholds its estimates (``EstimateFlag.UNSETTLED``). One refused
altitude among fifty, the case the gate is for, leaves it settled.
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Callable, Mapping
from typing import Any

UNSETTLED_WINDOW_S = 1.0
"""The window over which the share of refused altitudes is judged (s)."""


class InnovationGate:
    """One filter's gate and its rejected-since timer (see the module docstring)."""

    __slots__ = ("_recent", "_refused", "min_m", "reacquire_s", "rejected_since_ns", "sigma")

    def __init__(self, sigma: float | None, min_m: float, reacquire_s: float) -> None:
        self.sigma = sigma
        """Standard deviations of the innovation that close the gate (None: no gate)."""
        self.min_m = min_m
        self.reacquire_s = reacquire_s
        self.rejected_since_ns: int | None = None
        """When the current run of rejected altitudes began (None: the last was fused)."""
        self._recent: deque[tuple[int, bool]] = deque()
        """(t_ns, refused) of the altitudes judged within the last UNSETTLED_WINDOW_S."""
        self._refused = 0

    @property
    def unsettled(self) -> bool:
        """More than half the altitudes of the last UNSETTLED_WINDOW_S were refused."""
        return 2 * self._refused > len(self._recent)

    def _judged(self, t_ns: int, refused: bool) -> bool:
        recent = self._recent
        recent.append((t_ns, refused))
        self._refused += refused
        oldest = t_ns - round(UNSETTLED_WINDOW_S * 1e9)
        while recent[0][0] <= oldest:
            self._refused -= recent.popleft()[1]
        return not refused

    def forget(self) -> None:
        """The filter restarted: nothing it judged before says anything of the new state."""
        self.rejected_since_ns = None
        self._recent.clear()
        self._refused = 0

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
            return self._judged(t_ns, refused=False)
        if self.rejected_since_ns is None:
            self.rejected_since_ns = t_ns
        if (t_ns - self.rejected_since_ns) / 1e9 < self.reacquire_s:
            counts["gated"] += 1
            return self._judged(t_ns, refused=True)
        counts["reacquired"] += 1
        self.rejected_since_ns = None
        reacquire()
        # the new level is the filter's guess, not a fused altitude: the window still shows
        # what was refused before it
        self._judged(t_ns, refused=True)
        return True

    def as_dict(self) -> dict[str, Any]:
        """The gate's state, JSON-able (``Estimator.get_state``)."""
        return {"rejected_since_ns": self.rejected_since_ns,
                "recent": [[t, refused] for t, refused in self._recent]}

    def load_dict(self, state: Mapping[str, Any]) -> None:
        """The state ``as_dict`` gave (an empty mapping: a fresh gate)."""
        since = state.get("rejected_since_ns")
        self.rejected_since_ns = None if since is None else int(since)
        self._recent = deque((int(t), bool(r)) for t, r in state.get("recent") or ())
        self._refused = sum(r for _, r in self._recent)
