"""Magnetometer calibration: hard iron h and soft iron S in ``corrected = S (raw - h)``.

Two fits over readings taken while the board is turned through a slow figure of 8 in three
dimensions (the seed's "Magnetometer" procedure):

* ``minmax`` (the seed's formulas): per axis ``h_i = (max_i + min_i) / 2`` and radius
  ``r_i = (max_i - min_i) / 2``; ``S = diag(B / r_i)`` with B the mean radius. Cheap, but it
  ignores the off-diagonal soft iron and leans on the extremes (noise, outliers).
* ``ellipsoid``: an algebraic least-squares fit of the quadric
  ``x'Ax + b'x + c = 0`` (total least squares on normalised data), centre ``h = -A^-1 b / 2``,
  shape ``Q = A / (h'Ah - c)``; Q must be positive definite (an ellipsoid). Its symmetric
  square root from the eigen decomposition ``Q = V diag(l) V'`` gives
  ``S = B V diag(sqrt(l)) V'``, symmetric positive definite, mapping the ellipsoid onto a
  sphere of radius B. B, the field strength, is not observable from the shape alone: given
  (``field_ut``, e.g. from a geomagnetic model) it is used; otherwise B is the geometric mean
  of the semi-axes (det S = 1: soft iron taken to preserve volume).

Before trusting a fit: directions must cover the sphere (equal-area bins, see
:mod:`imuhal.calibration.sphere`), the field strength must be an Earth-like one, and the
corrected magnitudes must be constant (RMS residual). Otherwise CalibrationError says why and
what to do.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from datetime import datetime
from typing import Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field

from imuhal.calibration.errors import CalibrationError
from imuhal.calibration.model import MagCalibration
from imuhal.calibration.procedure import Procedure
from imuhal.calibration.progress import ProgressCallback, ProgressKind
from imuhal.calibration.sphere import Coverage, coverage
from imuhal.core.frames import FloatArray
from imuhal.core.samples import MagSample, Sample

Method = Literal["ellipsoid", "minmax"]
TURN_ADVICE = ("turn the board slowly through a figure of 8 in all three dimensions - level, "
               "upside down, on each side, nose up and down - away from steel, magnets and "
               "cables carrying current")


@dataclass(frozen=True)
class MagFit:
    hard_iron_ut: FloatArray
    soft_iron: FloatArray
    field_ut: float
    """Radius of the corrected sphere (uT): the fitted or the given field strength."""
    method: Method


@dataclass(frozen=True)
class MagResult:
    fit: MagFit
    coverage: Coverage
    residual_rms_ut: float
    """RMS of ``|S (raw - h)| - B`` over the readings (uT)."""
    samples: int
    axis_ratio: float
    """Longest over shortest semi-axis of the raw ellipsoid (1.0: no soft iron)."""

    @property
    def quality(self) -> dict[str, float]:
        return {
            "samples": float(self.samples),
            "coverage_pct": 100.0 * self.coverage.fraction,
            "field_ut": self.fit.field_ut,
            "residual_rms_ut": self.residual_rms_ut,
            "residual_rms_pct": 100.0 * self.residual_rms_ut / self.fit.field_ut,
            "axis_ratio": self.axis_ratio,
        }

    def record(self, date: datetime | None = None) -> MagCalibration:
        h, s = self.fit.hard_iron_ut, self.fit.soft_iron
        return MagCalibration(
            hard_iron_ut=(float(h[0]), float(h[1]), float(h[2])),
            soft_iron=tuple(tuple(float(x) for x in row) for row in s),
            procedure=f"mag-{self.fit.method}", date=date, quality=self.quality)


# --------------------------------------------------------------------------- the fits
def minmax_fit(raw: FloatArray, field_ut: float | None = None) -> MagFit:
    """The seed's hard-iron offsets and per-axis scale from the extremes of each axis."""
    x = np.asarray(raw, dtype=float)
    lo, hi = x.min(axis=0), x.max(axis=0)
    radius = (hi - lo) / 2.0
    if np.any(radius <= 0):
        raise CalibrationError("an axis never changed during the motion",
                               TURN_ADVICE.capitalize())
    b = float(field_ut) if field_ut else float(radius.mean())
    return MagFit((hi + lo) / 2.0, np.diag(b / radius), b, "minmax")


def ellipsoid_fit(raw: FloatArray, field_ut: float | None = None) -> MagFit:
    """Hard iron and a symmetric positive-definite soft-iron matrix from an ellipsoid fit."""
    x = np.asarray(raw, dtype=float)
    if len(x) < 10:
        raise CalibrationError(f"only {len(x)} magnetometer readings", TURN_ADVICE.capitalize())
    # Normalise (centre and scale) so the design matrix is well conditioned.
    mu = x.mean(axis=0)
    k = float(np.sqrt(np.mean(np.sum((x - mu) ** 2, axis=1)))) or 1.0
    p = (x - mu) / k
    px, py, pz = p.T
    d = np.c_[px * px, py * py, pz * pz, 2 * px * py, 2 * px * pz, 2 * py * pz,
              2 * px, 2 * py, 2 * pz, np.ones(len(p))]
    v = np.linalg.svd(d, full_matrices=False)[2][-1]
    a = np.array([[v[0], v[3], v[4]], [v[3], v[1], v[5]], [v[4], v[5], v[2]]])
    b = 2.0 * v[6:9]
    c = v[9]
    try:
        centre = -0.5 * np.linalg.solve(a, b)
    except np.linalg.LinAlgError:
        raise _not_ellipsoid() from None
    scale = float(centre @ a @ centre - c)
    if scale == 0.0:
        raise _not_ellipsoid()
    q = a / scale
    eig, vec = np.linalg.eigh(q)
    if np.any(eig <= 0):
        raise _not_ellipsoid()
    # back to raw units: p = (x - mu) / k, so the ellipsoid in x has shape Q / k^2
    eig = eig / (k * k)
    hard = mu + k * centre
    b_field = float(field_ut) if field_ut else float(np.prod(eig) ** (-1.0 / 6.0))
    soft = b_field * (vec @ np.diag(np.sqrt(eig)) @ vec.T)
    return MagFit(hard, soft, b_field, "ellipsoid")


def _not_ellipsoid() -> CalibrationError:
    return CalibrationError("the readings do not lie on an ellipsoid (too little motion, or a "
                            "disturbed field)", TURN_ADVICE.capitalize())


# --------------------------------------------------------------------------- checks
class MagSettings(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)

    method: Method = "ellipsoid"
    field_ut: float | None = Field(None, gt=0)
    """Known local field strength (uT); None: fitted (see the module docstring)."""
    min_coverage: float = Field(0.5, gt=0, le=1)
    """Fraction of direction cells that must be visited to accept a fit."""
    target_coverage: float = Field(0.75, gt=0, le=1)
    """The procedure stops collecting once this is reached (and ``min_samples``)."""
    min_samples: int = Field(300, ge=20)
    max_samples: int = Field(50_000, ge=100)
    max_residual_pct: float = Field(3.0, gt=0)
    """Largest RMS of ``|corrected| - B`` accepted, in % of B: above it the field changed
    while the board was turned."""
    field_range_ut: tuple[float, float] = (15.0, 100.0)
    """Plausible Earth field strengths (the Earth's is 22-67 uT at the surface)."""
    max_axis_ratio: float = Field(1.6, gt=1)
    """Longest over shortest semi-axis accepted; real soft iron stays well below."""


def evaluate(raw: FloatArray, settings: MagSettings | None = None) -> MagResult:
    """Fit ``raw`` readings (N x 3, uT, sensor frame) and check the fit; raise
    CalibrationError with the reason and what to do when it cannot be trusted."""
    s = settings or MagSettings()
    x = np.asarray(raw, dtype=float).reshape(-1, 3)
    if len(x) < s.min_samples:
        raise CalibrationError(f"only {len(x)} magnetometer readings (need {s.min_samples})",
                               f"{TURN_ADVICE.capitalize()}, for longer")
    cov = field_coverage(x, s)
    if cov.fraction < s.min_coverage:
        raise _coverage_error(cov, s)
    fit = ellipsoid_fit(x, s.field_ut) if s.method == "ellipsoid" else minmax_fit(x, s.field_ut)
    corrected = (x - fit.hard_iron_ut) @ fit.soft_iron.T
    sv = np.linalg.svd(fit.soft_iron, compute_uv=False)
    ratio = float(sv.max() / sv.min())
    residual = float(np.sqrt(np.mean((np.linalg.norm(corrected, axis=1) - fit.field_ut) ** 2)))
    result = MagResult(fit, cov, residual, len(x), ratio)
    figures = result.quality
    if residual > s.max_residual_pct / 100.0 * fit.field_ut:
        ellipsoid = _ellipsoid_fit_passing(x, s) if s.method == "minmax" else None
        if ellipsoid is not None:
            gaps = _extreme_gaps_deg(x, ellipsoid)
            missed = [f"{axis} by {gap:.0f} deg" for axis, gap in gaps.items() if gap > 5.0]
            why = (f"the motion never turned these sensor axes onto the field direction: "
                   f"{', '.join(missed)} (min/max needs every axis pointed along and against "
                   "the field)" if missed else
                   "the soft iron couples the axes, which min/max cannot model")
            raise CalibrationError(
                f"min/max leaves {residual:.2f} uT RMS "
                f"({100 * residual / fit.field_ut:.1f} %): {why}; the ellipsoid fit of the "
                "same readings passes",
                "use the ellipsoid fit (--method ellipsoid) on the same motion"
                + (", or turn the board until each of those axes points along and against "
                   "the field" if missed else ""), figures)
        raise CalibrationError(
            f"the field was disturbed: readings scatter {residual:.2f} uT RMS "
            f"({100 * residual / fit.field_ut:.1f} %, limit {s.max_residual_pct:g} %) around the "
            "fitted sphere",
            "move away from steel furniture, magnets, motors and cables carrying current, keep "
            "the board's own electronics in their flight state, and repeat", figures)
    lo, hi = s.field_range_ut
    if not lo <= fit.field_ut <= hi:
        raise CalibrationError(
            f"the fitted field strength {fit.field_ut:.1f} uT is not an Earth field "
            f"({lo:g}-{hi:g} uT)",
            "check the magnetometer range setting and move away from magnets, then repeat",
            figures)
    if ratio > s.max_axis_ratio:
        raise CalibrationError(
            f"the fitted soft iron stretches one axis {ratio:.2f} times another (limit "
            f"{s.max_axis_ratio:g})", f"the data are disturbed or too sparse; {TURN_ADVICE}",
            figures)
    return result


def field_coverage(raw: FloatArray, settings: MagSettings) -> Coverage:
    """The coverage of field directions that the live progress shows, the stop decision
    uses and the result reports: one computation, so the final quality line repeats the last
    figure the user saw (directions from the min/max centre, which needs no fit)."""
    return rough_coverage(np.asarray(raw, dtype=float).reshape(-1, 3),
                          settings.field_range_ut[0])


def rough_coverage(raw: FloatArray, min_radius_ut: float) -> Coverage:
    """Coverage of directions seen from the min/max centre, counting only readings at least
    ``min_radius_ut`` from it: a board held still gives a small noise cloud whose directions
    from its own centre point everywhere and must not count as coverage."""
    centre = (raw.max(axis=0) + raw.min(axis=0)) / 2.0
    d = raw - centre
    return coverage(d[np.linalg.norm(d, axis=1) >= min_radius_ut])


def _ellipsoid_fit_passing(x: FloatArray, s: MagSettings) -> MagFit | None:
    """The ellipsoid fit of ``x`` when it passes every check, else None."""
    try:
        return evaluate(x, s.model_copy(update={"method": "ellipsoid"})).fit
    except CalibrationError:
        return None


def _extreme_gaps_deg(x: FloatArray, fit: MagFit) -> dict[str, float]:
    """For each sensor axis and sign (``+x`` ...), how far (deg) the readings stayed from the
    extreme that axis reaches when it points along the field, per the ellipsoid ``fit``."""
    reach = fit.field_ut * np.linalg.norm(np.linalg.inv(fit.soft_iron), axis=1)
    out: dict[str, float] = {}
    for i, name in enumerate("xyz"):
        for sign, seen in (("+", x[:, i].max() - fit.hard_iron_ut[i]),
                           ("-", fit.hard_iron_ut[i] - x[:, i].min())):
            out[f"{sign}{name}"] = math.degrees(math.acos(float(np.clip(seen / reach[i],
                                                                        -1.0, 1.0))))
    return out


def _coverage_error(cov: Coverage, s: MagSettings) -> CalibrationError:
    missing = (f"; never near sensor {', '.join(cov.missing_axes)}" if cov.missing_axes else "")
    return CalibrationError(
        f"the motion covered {100 * cov.fraction:.0f} % of field directions (need "
        f"{100 * s.min_coverage:.0f} %){missing}",
        f"{TURN_ADVICE.capitalize()}, until coverage reaches {100 * s.target_coverage:.0f} %",
        {"coverage_pct": 100.0 * cov.fraction})


# --------------------------------------------------------------------------- the procedure
class MagCalibrationProcedure(Procedure[MagResult]):
    """Collect magnetometer readings until directions are covered, then fit and check."""

    name = "mag"

    def __init__(self, settings: MagSettings | None = None, *, device: str | None = None,
                 progress: ProgressCallback | None = None) -> None:
        super().__init__(device=device, progress=progress)
        self.settings = settings or MagSettings()
        self.name = f"mag-{self.settings.method}"
        self._raw: list[tuple[float, float, float]] = []
        self._started = False
        self.coverage = 0.0

    @property
    def readings(self) -> FloatArray:
        return np.asarray(self._raw, dtype=float).reshape(-1, 3)

    def _take(self, sample: Sample) -> bool:
        if not isinstance(sample, MagSample):
            return False
        s = self.settings
        if not self._started:
            self._started = True
            self.say(ProgressKind.INSTRUCTION, TURN_ADVICE.capitalize())
        self._raw.append(sample.mag_ut)
        n = len(self._raw)
        if n >= s.max_samples:
            return True
        if n % 50 == 0:
            x = self.readings
            self.coverage = field_coverage(x, s).fraction
            self.say(ProgressKind.PROGRESS, f"coverage {100 * self.coverage:.0f} % "
                     f"(target {100 * s.target_coverage:.0f} %), {n} readings",
                     min(1.0, self.coverage / s.target_coverage))
            return self.coverage >= s.target_coverage and n >= s.min_samples
        return False

    def finish(self) -> MagResult:
        return evaluate(self.readings, self.settings)
