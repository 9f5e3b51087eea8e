"""A GNSS receiver's vertical values held against the board's own barometer (issue 26).

The GNSS driver holds each epoch against the receiver's earlier epochs
(imuhal_chips.gnss.integrity), and some errors pass every rule the receiver's own data can
state: a velD spike under the velocity step limit, a height flip at 1 Hz (a 10 g vehicle
can leave its ramp by 25 m in a second), NMEA heights (no vAcc, and a vertical velocity made
from the heights themselves). The barometer on the same board measures the same vertical
motion independently, to a few centimetres over a second, so the pipeline (which alone sees
both devices; a driver knows only its own chip) holds the two against each other:

- **climb**: velD must equal minus the barometric climb at the epoch. The climb is the slope
  at the epoch's time of a least-squares parabola through the barometer's valid altitudes of
  the last ``BARO_BEFORE_S`` (ISA pressure altitude): the parabola takes a steady vertical
  acceleration without bias, wherever the epoch lies in the window, and its slope's variance
  comes from the fit's own residuals (noise and turbulence both widen it).
- **height**: the GNSS height less the barometric altitude at the epoch changes slowly (the
  receiver's height error wanders over tens of seconds; the barometer drifts with the
  weather and scales with the air's temperature), so it must stay where the last epoch that
  passed left it, within ``GATE_SIGMAS`` of how far the receiver's height error can move in
  the time between (the driver's Gauss-Markov bound, ``HEIGHT_ERROR_TAU_S``) and the fit's
  uncertainty, plus the ISA scale error on the altitude changed, the weather's drift and a
  time-stamp term.

Bounds carry what an honest pair can differ by and a margin; nothing here needs the
vehicle's acceleration limit, which is why the defaults catch what the receiver's own rules
cannot. A contradicted value is flagged ``CONTRADICTED``, counted, never fused, and is no
reference; the last of ``CONFIRM`` contradicted heights in a row that agree with one another
is valid and the new reference (a receiver whose height really moved against the barometer,
its satellite set changed: two epochs lost, no wrong one passed). Without barometer evidence
around the epoch (no barometer, or its samples flagged or lost) nothing is flagged: the
driver's own rules stand alone, as before.

What it does not do: hold the horizontal position or velocity (no sensor on the board
measures them), or integrate the IMU's vertical acceleration between epochs (that needs the
attitude, an estimator's output, which the validity stage must not depend on).
"""

from __future__ import annotations

import itertools
import math
from collections import deque
from dataclasses import dataclass, field

import numpy as np

from imuhal.core.atmosphere import altitude_m_from_pressure
from imuhal.core.samples import PositionSample, Sample, SampleFlag, VelocitySample

GATE_SIGMAS = 5.0
"""Standard deviations allowed, as the driver's own position rules."""
BARO_BEFORE_S = 0.8
"""The barometer's altitudes from this long before the epoch go into the fit (with those
after it that have arrived): 40 at 50 Hz, enough for a slope to 0.1 m/s."""
BARO_AFTER_S = 0.3
"""And those up to this long after the epoch."""
MIN_BEFORE_S = 0.4
"""The fit must reach back at least this far ..."""
MAX_LEAD_S = 0.15
"""... and its newest altitude lie no earlier than this before the epoch (a parabola
extrapolated further is no evidence)."""
MIN_ALTITUDES = 10
"""Fewer valid altitudes in the window: no evidence (not flagged)."""
BARO_NOISE_FLOOR_M = 0.05
"""The smallest altitude noise the fit's residuals are taken to show (a short run of
quiet samples understates it)."""
SCALE_ERROR = 0.15
"""How far the ISA pressure altitude's changes can differ from true height changes: the air
40 K off the standard atmosphere's temperature (a hot summer day at altitude) scales them by
14 %."""
WEATHER_M_S = 0.01
"""How fast the weather moves the barometric altitude (m/s): a passing front's 3 hPa an hour
is 0.007 m/s."""
STAMP_LAG_S = 0.25
"""How much earlier than its time stamp a receiver's epoch may have been measured (s): a
driver stamps an epoch by its arrival less the latency its profile states (none by
default), and a u-blox sends its solution 50-100 ms after the epoch, plus the frame's time
on the line (100 ms for a NAV-PVT at 9600 baud). velD is held against the barometer's climb
anywhere in that span, and the height gets the climb over it (in a pull-up, 4 g, the climb
moves 10 m/s in 0.25 s)."""
HEIGHT_MARGIN_M = 1.5
"""Added to the height bound: a static port's own errors (airflow around the harness)."""
CLIMB_MARGIN_M_S = 0.7
"""Added to the climb bound, for the same reason, and a receiver's velocity latency."""
HEIGHT_ERROR_TAU_S = 10.0
"""The shortest correlation time of a receiver's height error (imuhal_chips.gnss.integrity's
value and reasons: the bound errs on the loose side)."""
UNKNOWN_VERTICAL_ACCURACY_M = 10.0
"""vAcc taken when the receiver states none (NMEA): a poor consumer receiver's."""
UNKNOWN_SPEED_ACCURACY_M_S = 2.0
"""sAcc taken when the receiver states none (NMEA, whose vertical velocity is made from
heights a second apart: 1.7 m/s rms at vAcc 4 m)."""
CONFIRM = 3
"""Contradicted heights in a row that agree with one another: the last is valid and the new
reference (the driver's rule for its own references, imuhal_chips.gnss.integrity)."""
HISTORY_S = 3.0
"""The barometer's altitudes kept (s)."""
NS = 1e-9


@dataclass(frozen=True)
class BaroFit:
    """The barometer at one epoch: altitude (m, ISA) and climb (m/s, up) with variances."""

    altitude_m: float
    altitude_var_m2: float
    climb_m_s: float
    climb_var: float
    accel_m_s2: float
    """The parabola's vertical acceleration (m/s^2, up)."""

    def climb_range_m_s(self, lag_s: float) -> tuple[float, float]:
        """The climb the parabola gives from ``lag_s`` before the epoch to the epoch."""
        a, b = self.climb_m_s, self.climb_m_s - self.accel_m_s2 * lag_s
        return (a, b) if a <= b else (b, a)


@dataclass
class _Reference:
    t_ns: int
    offset_m: float
    """GNSS height less barometric altitude (m)."""
    offset_var_m2: float
    altitude_m: float
    vertical_accuracy_m: float


@dataclass
class CrossCheckStats:
    """What the check did (counts of samples)."""

    checked: dict[str, int] = field(default_factory=lambda: {"height": 0, "climb": 0})
    contradicted: dict[str, int] = field(default_factory=lambda: {"height": 0, "climb": 0})
    new_references: int = 0
    """Times CONFIRM contradicted heights in a row agreed and became the reference."""
    no_evidence: int = 0
    """GNSS values left to the driver's rules: no barometer altitudes around their epoch."""
    worst_ratio: dict[str, float] = field(default_factory=lambda: {"height": 0.0,
                                                                   "climb": 0.0})
    """The largest residual / bound of a value that passed (how close honest data come)."""


class VerticalCrossCheck:
    """Holds GNSS heights and velD against one barometer (``baro``: its device name)."""

    def __init__(self, baro: str) -> None:
        self.baro = baro
        self._altitudes: deque[tuple[int, float]] = deque()
        self._fits: dict[int, BaroFit | None] = {}
        self._reference: _Reference | None = None
        self._pending: list[_Reference] = []
        self._speed_accuracy_m_s: float | None = None
        """The stated sAcc of the last velocity that passed (m/s)."""
        self.stats = CrossCheckStats()

    def observe(self, sample: Sample) -> Sample:
        """``sample`` after the check: a valid barometer pressure is kept, a valid GNSS
        velocity or position the barometer contradicts comes back flagged CONTRADICTED;
        anything else as it came."""
        if sample.flags:
            return sample
        if isinstance(sample, VelocitySample):
            return self._check_climb(sample)
        if isinstance(sample, PositionSample):
            return self._check_height(sample)
        if sample.device == self.baro:
            value = getattr(sample, "pressure_pa", None)
            if value is not None and value > 0.0:
                self._keep(sample.t_ns, altitude_m_from_pressure(value))
        return sample

    # -- the barometer ------------------------------------------------------------------

    def _keep(self, t_ns: int, altitude_m: float) -> None:
        alts = self._altitudes
        alts.append((t_ns, altitude_m))
        oldest = t_ns - int(HISTORY_S / NS)
        while alts[0][0] < oldest:
            alts.popleft()

    def fit(self, t_ns: int) -> BaroFit | None:
        """The barometer's altitude and climb at ``t_ns`` (None: too few altitudes around
        it); one fit per epoch (its velocity and position share it)."""
        if t_ns in self._fits:
            return self._fits[t_ns]
        if len(self._fits) > 8:
            self._fits.clear()
        result = self._fit(t_ns)
        self._fits[t_ns] = result
        return result

    def _fit(self, t_ns: int) -> BaroFit | None:
        lo, hi = t_ns - int(BARO_BEFORE_S / NS), t_ns + int(BARO_AFTER_S / NS)
        window = [(t, h) for t, h in self._altitudes if lo <= t <= hi]
        if len(window) < MIN_ALTITUDES:
            return None
        x = np.array([(t - t_ns) * NS for t, _ in window])
        if x[0] > -MIN_BEFORE_S or x[-1] < -MAX_LEAD_S:
            return None
        y = np.array([h for _, h in window])
        design = np.column_stack((np.ones_like(x), x, x * x))
        coef, rss, rank, _ = np.linalg.lstsq(design, y, rcond=None)
        if rank < 3:
            return None
        dof = len(x) - 3
        resid = float(rss[0]) if len(rss) else float(np.sum((design @ coef - y) ** 2))
        noise_var = max(resid / dof, BARO_NOISE_FLOOR_M ** 2)
        cov = np.linalg.inv(design.T @ design) * noise_var
        return BaroFit(altitude_m=float(coef[0]), altitude_var_m2=float(cov[0, 0]),
                       climb_m_s=float(coef[1]), climb_var=float(cov[1, 1]),
                       accel_m_s2=2.0 * float(coef[2]))

    # -- the checks ---------------------------------------------------------------------

    def climb_bound_m_s(self, fit: BaroFit, speed_accuracy_m_s: float) -> float:
        """How far velD may differ from minus the barometric climb (m/s)."""
        return (GATE_SIGMAS * math.sqrt(speed_accuracy_m_s ** 2 + fit.climb_var)
                + SCALE_ERROR * abs(fit.climb_m_s) + CLIMB_MARGIN_M_S)

    def _check_climb(self, sample: VelocitySample) -> Sample:
        fit = self.fit(sample.t_ns)
        if fit is None:
            self.stats.no_evidence += 1
            return sample
        stated = sample.accuracy_m_s if sample.accuracy_m_s is not None \
            else UNKNOWN_SPEED_ACCURACY_M_S
        # sAcc comes from the same frame as velD: a flip that hit both (sAcc 16 m/s, velD
        # 16 m/s off) must not widen its own bound, so it counts no worse than the last
        # velocity that passed (the driver's rule for hAcc and vAcc)
        last = self._speed_accuracy_m_s
        s_acc = stated if last is None else min(stated, last)
        low, high = fit.climb_range_m_s(STAMP_LAG_S)
        climb = -sample.velocity_ned_m_s[2]
        residual = max(low - climb, climb - high, 0.0)
        bound = self.climb_bound_m_s(fit, s_acc)
        self.stats.checked["climb"] += 1
        if residual > bound:
            self.stats.contradicted["climb"] += 1
            return sample.flagged(SampleFlag.CONTRADICTED)
        self._speed_accuracy_m_s = stated
        self._worst("climb", residual / bound)
        return sample

    def height_bound_m(self, ref: _Reference, new: _Reference, climb_m_s: float) -> float:
        """How far the GNSS height less the barometric altitude may move from ``ref`` to
        ``new`` (m)."""
        dt = abs(new.t_ns - ref.t_ns) * NS
        # the new epoch's vAcc counts no worse than the reference's: the same frame says it
        v_acc = min(ref.vertical_accuracy_m, new.vertical_accuracy_m)
        drift = v_acc * math.sqrt(2.0 * (1.0 - math.exp(-dt / HEIGHT_ERROR_TAU_S)))
        return (GATE_SIGMAS * math.sqrt(drift ** 2 + ref.offset_var_m2 + new.offset_var_m2)
                + SCALE_ERROR * abs(new.altitude_m - ref.altitude_m) + WEATHER_M_S * dt
                + STAMP_LAG_S * abs(climb_m_s) + HEIGHT_MARGIN_M)

    def _check_height(self, sample: PositionSample) -> Sample:
        fit = self.fit(sample.t_ns)
        if fit is None:
            self.stats.no_evidence += 1
            return sample
        v_acc = sample.vertical_accuracy_m
        new = _Reference(t_ns=sample.t_ns, offset_m=sample.height_m - fit.altitude_m,
                         offset_var_m2=fit.altitude_var_m2, altitude_m=fit.altitude_m,
                         vertical_accuracy_m=UNKNOWN_VERTICAL_ACCURACY_M if v_acc is None
                         else v_acc)
        ref = self._reference
        if ref is None:
            self._reference = new
            return sample
        self.stats.checked["height"] += 1
        residual = abs(new.offset_m - ref.offset_m)
        bound = self.height_bound_m(ref, new, fit.climb_m_s)
        if residual <= bound:
            self._reference = new
            self._pending.clear()
            self._worst("height", residual / bound)
            return sample
        self._pending = [*self._pending[1 - CONFIRM:], new]
        pending = self._pending
        if len(pending) == CONFIRM and all(
                abs(b.offset_m - a.offset_m) <= self.height_bound_m(a, b, fit.climb_m_s)
                for a, b in itertools.pairwise(pending)):
            # the receiver's height really moved against the barometer (its satellite set
            # changed): the epochs before this one are lost, this one is the new reference
            self._reference = new
            self._pending.clear()
            self.stats.new_references += 1
            return sample
        self.stats.contradicted["height"] += 1
        return sample.flagged(SampleFlag.CONTRADICTED)

    def _worst(self, what: str, ratio: float) -> None:
        if ratio > self.stats.worst_ratio[what]:
            self.stats.worst_ratio[what] = ratio
