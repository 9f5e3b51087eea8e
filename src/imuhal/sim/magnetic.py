"""Magnetic disturbances added to the earth field: a scenario-level effect with known truth.

Two kinds, both in NED (uT) and both pure functions of time and seed:

* slow: a seeded, band-limited drift on each NED axis (steel moving nearby, a car parked
  next to the launch site, currents in a harness), periods of minutes;
* fast: permanent magnets passing the board along straight lines (a dipole field, which
  grows as 1/r^3 near the closest approach and is large enough to saturate a magnetometer).

A magnet pass is described relative to the board: the magnet moves along ``path_direction``
at ``speed_m_s`` and is closest (``closest_distance_m``, in direction ``offset_direction``
from the board) at ``t_closest_s``.
"""

from __future__ import annotations

import math

import numpy as np
from pydantic import Field, model_validator

from imuhal.sim.scenario import ScenarioParams
from imuhal.sim.signals import Signal

Vec3 = tuple[float, float, float]

_MU0_OVER_4PI_UT = 0.1
"""mu0 / (4 pi) = 1e-7 T m / A; times 1e6 for uT."""


class MagnetPass(ScenarioParams):
    """One magnet passing the board (all directions NED, normalised on use)."""

    t_closest_s: float
    closest_distance_m: float = Field(0.08, gt=0)
    speed_m_s: float = Field(0.2, gt=0)
    moment_a_m2: float = Field(0.5, gt=0)
    """Dipole moment; a 1 cm^3 NdFeB cube is about 1 A m^2."""
    moment_direction: Vec3 = (1.0, 0.0, 0.0)
    path_direction: Vec3 = (0.0, 1.0, 0.0)
    offset_direction: Vec3 = (0.0, 0.0, -1.0)
    """From the board to the point of closest approach; made perpendicular to the path."""

    @model_validator(mode="after")
    def _directions(self) -> MagnetPass:
        for name in ("moment_direction", "path_direction", "offset_direction"):
            if math.hypot(*getattr(self, name)) == 0:
                raise ValueError(f"{name} must not be the zero vector")
        u = np.asarray(self.path_direction, float)
        o = np.asarray(self.offset_direction, float)
        if np.linalg.norm(o - (o @ u) / (u @ u) * u) < 1e-9:
            raise ValueError("offset_direction must not be parallel to path_direction")
        return self


class MagneticDisturbanceSpec(ScenarioParams):
    """Disturbances of the field at the board. Default: none."""

    slow_rms_ut: float = Field(0.0, ge=0)
    """RMS of the slow drift on each NED axis."""
    slow_min_period_s: float = Field(60.0, gt=0)
    slow_max_period_s: float = Field(600.0, gt=0)
    slow_ramp_s: float = Field(5.0, gt=0)
    """The drift fades in over this time after t = 0."""
    passes: tuple[MagnetPass, ...] = ()


class MagneticDisturbance:
    """Evaluates a :class:`MagneticDisturbanceSpec` for one seed: ``field_ned(t)`` in uT."""

    def __init__(self, spec: MagneticDisturbanceSpec, seed: int = 0) -> None:
        self.spec = spec
        rng = np.random.default_rng([int(seed), 0x3A6])
        self._slow: tuple[Signal, Signal, Signal] | None = None
        if spec.slow_rms_ut > 0:
            self._slow = tuple(  # type: ignore[assignment]  # a generator over range(3): three signals
                Signal().turbulence(rng, spec.slow_rms_ut, f_min_hz=1.0 / spec.slow_max_period_s,
                                    f_max_hz=1.0 / spec.slow_min_period_s, tones=6,
                                    ramp_s=spec.slow_ramp_s)
                for _ in range(3))
        self._passes = [self._prepare(p) for p in spec.passes]

    @staticmethod
    def _prepare(p: MagnetPass) -> tuple[float, float, Vec3, Vec3, Vec3]:
        u = np.asarray(p.path_direction, float)
        u /= np.linalg.norm(u)
        o = np.asarray(p.offset_direction, float)
        o = o - (o @ u) * u
        o /= np.linalg.norm(o)
        m = np.asarray(p.moment_direction, float)
        m = m / np.linalg.norm(m) * p.moment_a_m2
        # Beyond this distance along the path the field is below 1e-6 of its peak: skip.
        reach = p.closest_distance_m * 100.0 / p.speed_m_s
        def tup(a: np.ndarray) -> Vec3:
            return (float(a[0]), float(a[1]), float(a[2]))

        return (p.t_closest_s, reach, tup(o * p.closest_distance_m), tup(u * p.speed_m_s),
                tup(m))

    @property
    def active(self) -> bool:
        return self._slow is not None or bool(self._passes)

    def field_ned(self, t_s: float) -> Vec3:
        """The disturbance field (uT, NED) at the board at time ``t_s``."""
        bn = be = bd = 0.0
        if self._slow is not None:
            bn, be, bd = (s(t_s)[0] for s in self._slow)
        for tc, reach, c, vel, m in self._passes:
            dt = t_s - tc
            if abs(dt) > reach:
                continue
            # r: from the magnet to the board.
            rx, ry, rz = -(c[0] + vel[0] * dt), -(c[1] + vel[1] * dt), -(c[2] + vel[2] * dt)
            r2 = rx * rx + ry * ry + rz * rz
            r = math.sqrt(r2)
            mr = (m[0] * rx + m[1] * ry + m[2] * rz) / r2
            k = _MU0_OVER_4PI_UT / (r2 * r)
            bn += k * (3.0 * mr * rx - m[0])
            be += k * (3.0 * mr * ry - m[1])
            bd += k * (3.0 * mr * rz - m[2])
        return (bn, be, bd)
