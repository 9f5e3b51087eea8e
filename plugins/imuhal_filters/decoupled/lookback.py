"""The accelerometer filter's look-back: what the manoeuvre detector decides late, or wrongly.

The manoeuvre detector (common/innovation.py) needs a few tenths of a second to see a
manoeuvre, which the inclination filter has by then taken nearly in full; so the filter
input of the last ``lookback_s`` is kept, with the filter as it was before it, and when the
weight drops below one half that stretch is filtered again with the new weight.

The detector's steadiness statistic can also be wrong: the first quarter of a hand's stroke,
or a slow smooth stroke's turn-round, is a steady acceleration for half a second (BROAD's
slow translations). Withholding it alone is worse than taking it: the filter averages the
hand's acceleration out only when every phase of a stroke has the same weight, and it would
then take the stroke's other half in full. What tells a stroke from a manoeuvre afterwards is
the velocity: a hand brings the board back, a vehicle's push keeps its velocity change. So
from the stretch a closure re-weighted (an **episode**), the input is kept and the
innovation integrated into the velocity change since the episode began. When that change
comes back (its component along its largest value so far is zero or less, or the board comes
to rest), the acceleration has averaged out over the episode, and the whole episode is
filtered again in full (its other weights, the soft gate's, kept). An episode ends without
that when its velocity change exceeds the detector's speed bound (no hand does that) or it
has lasted the detector's leak time (the time within which a hand's motion comes back).
"""

from __future__ import annotations

import math
from collections import deque
from typing import Any

from imuhal_filters.common.quat import Vec
from imuhal_filters.decoupled.butterworth import ButterworthLowPass

Entry = list[float]
"""One kept filter input: the reading in the almost-inertial frame (g, 3 values), the step
(s), the weight it was filtered with, its weight without the manoeuvre detector, and the
innovation against the filter's gravity before it, its slow drift taken out (m/s^2, 3), and
the pace the filter ran at (pace.py: its step lengthened by this factor)."""
_DT, _WEIGHT, _BASE, _INNOVATION, _PACE = 3, 4, 5, 6, 9


def _dot(a: list[float], b: list[float]) -> float:
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


def _filter_dt(e: Entry) -> float:
    """The step the filter takes for a kept input (s; entries saved before the pace: 1)."""
    return e[_DT] * e[_WEIGHT] * (e[_PACE] if len(e) > _PACE else 1.0)


class LookBack:
    """The kept filter input and the accelerometer filter as it was before it."""

    def __init__(self, tau_acc_s: float, lookback_s: float, episode_max_s: float,
                 speed_m_s: float, tolerance_m_s: float) -> None:
        self.lookback_s = lookback_s
        self.tolerance_m_s = tolerance_m_s
        self.episode_max_s = episode_max_s
        self.speed_m_s = speed_m_s
        self.entries: deque[Entry] = deque()
        self.kept_s = 0.0
        self.before = ButterworthLowPass(tau_acc_s)
        """The filter before the first entry (no state until an entry has left)."""
        self.last_weight = 1.0
        self.episode_s: float | None = None
        """How long the current episode has lasted (s); None: no episode."""
        self.dv_m_s = [0.0, 0.0, 0.0]
        self.peak_m_s = [0.0, 0.0, 0.0]
        self.readmitted = 0
        """Episodes filtered again in full (strokes the steadiness statistic mistook)."""

    # ------------------------------------------------------------------ state
    def as_dict(self) -> dict[str, Any]:
        """The state, JSON-ready."""
        return {"entries": [list(e) for e in self.entries], "kept_s": self.kept_s,
                "before": self.before.state, "last_weight": self.last_weight,
                "episode_s": self.episode_s, "dv_m_s": list(self.dv_m_s),
                "peak_m_s": list(self.peak_m_s), "readmitted": self.readmitted}

    def load_dict(self, d: dict[str, Any]) -> None:
        self.entries = deque([float(c) for c in e] for e in d["entries"])
        self.kept_s = float(d["kept_s"])
        self.before.state = None if d["before"] is None else [float(c) for c in d["before"]]
        self.last_weight = float(d["last_weight"])
        self.episode_s = None if d["episode_s"] is None else float(d["episode_s"])
        self.dv_m_s = [float(c) for c in d["dv_m_s"]]
        self.peak_m_s = [float(c) for c in d["peak_m_s"]]
        self.readmitted = int(d["readmitted"])

    # ------------------------------------------------------------------ step
    def step(self, filt: ButterworthLowPass, a: Vec, dt: float, weight: float, base: float,
             innovation_m_s2: Vec, rest: bool, pace: float = 1.0) -> tuple[float, bool]:
        """Keep one input of the accelerometer filter ``filt`` before it takes it: ``a`` (g,
        almost-inertial frame) over ``dt`` s, the step's ``weight``, its weight ``base``
        without the manoeuvre detector, the innovation (``Entry``), whether the board is at
        rest and the ``pace`` the filter runs at. Returns the weight to filter it with and
        whether ``filt``'s state was replaced (the kept input filtered again)."""
        replaced = False
        closing = weight < 0.5 <= self.last_weight
        self.last_weight = weight
        if closing and self.entries and self.before.state is not None:
            self._reweight_recent(weight)
            if self.episode_s is None:
                self._start_episode()
            replaced = True
        if self.episode_s is not None and self._came_back(innovation_m_s2, dt, rest):
            for e in self.entries:
                e[_WEIGHT] = e[_BASE]
            weight = base
            self.readmitted += 1
            replaced = True
        if replaced:
            self._replay(filt)
        self.entries.append([a[0], a[1], a[2], dt, weight, base, *innovation_m_s2, pace])
        self.kept_s += dt
        if self.episode_s is None:
            self._trim()
        return weight, replaced

    def _reweight_recent(self, weight: float) -> None:
        """The last ``lookback_s`` of the kept input takes the new weight."""
        span = 0.0
        for e in reversed(self.entries):
            if span >= self.lookback_s:
                break
            e[_WEIGHT] = weight
            span += e[_DT]

    def _start_episode(self) -> None:
        """An episode begins with the kept input: its velocity change so far."""
        self.episode_s = self.kept_s
        dv = [0.0, 0.0, 0.0]
        for e in self.entries:
            for i in range(3):
                dv[i] += e[_INNOVATION + i] * e[_DT]
        self.dv_m_s, self.peak_m_s = dv, list(dv)

    def _came_back(self, innovation_m_s2: Vec, dt: float, rest: bool) -> bool:
        """Fold one step into the episode; True when its velocity change came back (the
        episode is then over, to be filtered again in full). The episode also ends, as a
        manoeuvre, beyond the detector's speed bound or after ``episode_max_s``."""
        assert self.episode_s is not None
        self.episode_s += dt
        dv, peak = self.dv_m_s, self.peak_m_s
        for i in range(3):
            dv[i] += innovation_m_s2[i] * dt
        if _dot(dv, dv) > _dot(peak, peak):
            self.peak_m_s = peak = list(dv)
        peak_sq = _dot(peak, peak)
        tol = self.tolerance_m_s
        back = rest or (peak_sq > tol * tol and _dot(dv, peak) <= tol * math.sqrt(peak_sq))
        if (back or peak_sq > self.speed_m_s * self.speed_m_s
                or self.episode_s > self.episode_max_s):
            self.episode_s = None
        return back

    def _trim(self) -> None:
        """Keep only the last ``lookback_s``; what leaves goes into the filter before it."""
        while self.kept_s > self.lookback_s and self.entries:
            e = self.entries.popleft()
            self.kept_s -= e[_DT]
            self.before.step((e[0], e[1], e[2]), _filter_dt(e))

    def _replay(self, filt: ButterworthLowPass) -> None:
        """Filter the kept input again, from the state before it, into ``filt``."""
        assert self.before.state is not None
        filt.state = list(self.before.state)
        for e in self.entries:
            filt.step((e[0], e[1], e[2]), _filter_dt(e))
