"""The magnetometer's hard iron learned in flight, from the field's rotation in turns.

A magnetometer without hard iron reads the Earth's field, whose length B is the same in
every attitude; with a hard iron h (a body-fixed offset, sensor frame, uT) its readings m lie
on a sphere of radius B around h: ``|m - h|^2 = B^2``, which is linear in the unknowns
``(h, c = B^2 - |h|^2)``: ``2 m . h + c = |m|^2``. Every reading adds one equation; the
normal equations are accumulated (4 x 4, no readings kept) and solved when asked. A board
that turns (a glider circling in a thermal, banked, turns the field through a cone about
the vertical) spreads the readings over the sphere; a board at rest repeats one reading,
which is why a reading is only taken when it lies ``min_step_ut`` from the previous one
taken (the noise of a still board does not fill the sphere).

Uncertainty: the least-squares covariance ``sigma^2 (A^T A)^-1`` with sigma^2 the residual
variance of the equations, never below what a reading noise of ``noise_floor_ut`` gives.
A steady turn puts every reading on one circle, which lies on many spheres: the fit needs
the bank to change (into and out of turns, turns both ways), and says so through the
uncertainty until it does. An axis the motion never turns onto the field shows as a large
standard deviation. **Convergence criterion**: at least ``min_readings`` readings taken and
the standard deviation of every axis of h at most ``max_std_ut``
(:class:`~imuhal.calibration.model.MagInFlightSettings`). Soft iron is not learned (it
needs the whole sphere; ``imuhal calibrate mag`` fits it); the sphere fit absorbs a mild
soft iron into B.
"""

from __future__ import annotations

import math
from datetime import datetime

import numpy as np

from imuhal.calibration.model import (
    CalibrationBinding,
    MagCalibration,
    MagInFlightSettings,
    Vec3,
)

PROCEDURE = "mag-in-flight"


class HardIronLearner:
    """Push-style: :meth:`feed` each raw sensor-frame reading (uT); :attr:`converged` once
    the criterion holds, then :meth:`record`."""

    def __init__(self, settings: MagInFlightSettings | None = None) -> None:
        self.settings = settings or MagInFlightSettings()
        self._n = np.zeros((4, 4))
        self._r = np.zeros(4)
        self._b2 = 0.0
        self._last: tuple[float, float, float] | None = None
        self.readings = 0
        """Readings taken into the fit (each min_step_ut from the previous one)."""
        self.converged = False
        self.latest: dict[str, object] = self.status()
        """:meth:`status` as of the last tenth reading: what another thread (the live
        view) reads, replaced whole, never half-updated."""

    def feed(self, mag_ut: Vec3) -> bool:
        """Take one raw reading; True when there is a new learned value to apply: when the
        fit converges, and every 10 readings taken after that (the fit keeps improving)."""
        x, y, z = (float(v) for v in mag_ut)
        last = self._last
        step = self.settings.min_step_ut
        if last is not None and (x - last[0])**2 + (y - last[1])**2 + (z - last[2])**2 \
                < step * step:
            return False
        self._last = (x, y, z)
        a = np.array([2.0 * x, 2.0 * y, 2.0 * z, 1.0])
        b = x * x + y * y + z * z
        self._n += np.outer(a, a)
        self._r += a * b
        self._b2 += b * b
        self.readings += 1
        # checked every 10 readings: a 4 x 4 solve, not one per sample
        if self.readings % 10:
            return False
        if not self.converged and self.readings >= self.settings.min_readings:
            std = self.std_ut()
            self.converged = std is not None and max(std) <= self.settings.max_std_ut
        self.latest = self.status()
        return self.converged

    def _solve(self) -> tuple[np.ndarray, np.ndarray] | None:
        """The fitted (h, c) and their covariance, or None while the fit is singular."""
        if self.readings < 5:
            return None
        if np.linalg.cond(self._n) > 1e12:  # the readings do not determine a sphere yet
            return None
        inv = np.linalg.inv(self._n)
        theta = inv @ self._r
        sse = self._b2 - 2.0 * float(theta @ self._r) + float(theta @ self._n @ theta)
        # residual of |m|^2 per reading; a reading noise s gives about (2 B s)^2
        b2 = max(float(theta[3] + theta[:3] @ theta[:3]), 0.0)
        floor = (2.0 * self.settings.noise_floor_ut) ** 2 * b2
        sigma2 = max(max(sse, 0.0) / (self.readings - 4), floor)
        return theta, sigma2 * inv

    def hard_iron_ut(self) -> Vec3 | None:
        """The hard iron fitted so far (sensor frame, uT), None before any fit."""
        fit = self._solve()
        if fit is None:
            return None
        h = fit[0][:3]
        return (float(h[0]), float(h[1]), float(h[2]))

    def std_ut(self) -> Vec3 | None:
        """The fitted hard iron's standard deviation per axis (uT), None before any fit."""
        fit = self._solve()
        if fit is None:
            return None
        # a variance that rounding made zero or negative belongs to a degenerate fit
        var = np.diag(fit[1])[:3]
        d = np.where(var > 0.0, np.sqrt(np.abs(var)), math.inf)
        return (float(d[0]), float(d[1]), float(d[2]))

    def field_ut(self) -> float | None:
        """The fitted field strength B (uT), None before a fit or if it is not real."""
        fit = self._solve()
        if fit is None:
            return None
        theta = fit[0]
        b2 = float(theta[3] + theta[:3] @ theta[:3])
        return math.sqrt(b2) if b2 > 0 else None

    def status(self) -> dict[str, object]:
        """What the run's health shows: readings, the fit so far and its uncertainty (per
        axis; None for an axis not determined yet), and the convergence criterion."""
        std = self.std_ut()
        return {"readings": self.readings, "converged": self.converged,
                "hard_iron_ut": self.hard_iron_ut(),
                # an axis the motion has not determined: None (JSON has no infinity)
                "std_ut": None if std is None else
                tuple(v if math.isfinite(v) else None for v in std),
                "field_ut": self.field_ut(),
                "criterion": {"min_readings": self.settings.min_readings,
                              "max_std_ut": self.settings.max_std_ut}}

    def record(self, *, binding: CalibrationBinding | None = None,
               date: datetime | None = None) -> MagCalibration:
        """The learned hard iron as a magnetometer record (soft iron: identity), with its
        quality figures, to save into the profile."""
        h, std, field = self.hard_iron_ut(), self.std_ut(), self.field_ut()
        if h is None or std is None:
            raise ValueError("no hard iron learned yet")
        quality = {"readings": float(self.readings), "std_x_ut": std[0], "std_y_ut": std[1],
                   "std_z_ut": std[2]}
        if field is not None:
            quality["field_ut"] = field
        return MagCalibration(hard_iron_ut=h, procedure=PROCEDURE, binding=binding, date=date,
                              quality=quality)
