"""Trajectories from recorded truth (a truth CSV or arrays), and the ``replay`` scenario.

Interpolation keeps the kinematics exactly self-consistent between the recorded samples:

* attitude turns at a constant body rate between samples (``q(t) = q_i exp(w_i (t - t_i)/2)``
  with ``w_i = 2 log(q_i^-1 q_i+1) / dt``): the rate integrates to the attitude exactly;
* position is the cubic Hermite curve through the recorded positions and velocities
  (velocities estimated by central differences when the record has none); velocity and
  acceleration are its exact derivatives.
"""

from __future__ import annotations

import math
from bisect import bisect_right
from typing import Any, ClassVar

import numpy as np
from numpy.typing import ArrayLike

from imuhal.core.atmosphere import STANDARD_GRAVITY_M_S2
from imuhal.sim.motion import Kinematics, Motion, mat_t_vec, quat_axis_angle, quat_matrix, quat_mul
from imuhal.sim.truth_csv import read_truth_csv
from imuhal.sim.world import MotionScenario, WorldParams


class RecordedMotion(Motion):
    """Interpolated kinematics from samples at increasing times ``t_s`` (s)."""

    def __init__(self, t_s: ArrayLike, q_body_to_ned: ArrayLike, position_ned_m: ArrayLike,
                 velocity_ned_m_s: ArrayLike | None = None, *,
                 gravity_m_s2: float = STANDARD_GRAVITY_M_S2) -> None:
        t = np.asarray(t_s, dtype=float)
        q = np.asarray(q_body_to_ned, dtype=float).copy()
        p = np.asarray(position_ned_m, dtype=float)
        if t.ndim != 1 or len(t) < 2:
            raise ValueError("a recorded trajectory needs at least two samples")
        if np.any(np.diff(t) <= 0):
            raise ValueError("recorded times must be strictly increasing")
        if q.shape != (len(t), 4) or p.shape != (len(t), 3):
            raise ValueError("q must be (N, 4) and position (N, 3) for N times")
        q /= np.linalg.norm(q, axis=1, keepdims=True)
        for i in range(1, len(q)):          # keep the sign continuous (shortest arcs)
            if q[i] @ q[i - 1] < 0:
                q[i] = -q[i]
        if velocity_ned_m_s is None:
            v = np.gradient(p, t, axis=0)
        else:
            v = np.asarray(velocity_ned_m_s, dtype=float)
        self.gravity_m_s2 = float(gravity_m_s2)
        self.t = t.tolist()
        self._t0, self._t1 = float(t[0]), float(t[-1])
        self._q = [tuple(map(float, r)) for r in q]
        self._p = [tuple(map(float, r)) for r in p]
        self._v = [tuple(map(float, r)) for r in v]
        self._w: list[tuple[float, float, float]] = []
        for i in range(len(t) - 1):
            a = self._q[i]
            dq = quat_mul((a[0], -a[1], -a[2], -a[3]), self._q[i + 1])  # type: ignore[arg-type]  # four columns of the truth CSV: a quaternion of four
            vec = math.sqrt(dq[1] ** 2 + dq[2] ** 2 + dq[3] ** 2)
            angle = 2.0 * math.atan2(vec, dq[0])
            k = 0.0 if vec < 1e-15 else angle / vec / (t[i + 1] - t[i])
            self._w.append((dq[1] * k, dq[2] * k, dq[3] * k))

    @property
    def span_s(self) -> tuple[float, float]:
        return self._t0, self._t1

    def kinematics(self, t_s: float) -> Kinematics:
        t = float(t_s)
        if t < self._t0:
            return self._extrapolated(t, 0, 0)
        if t > self._t1:
            return self._extrapolated(t, len(self.t) - 1, len(self._w) - 1)
        i = min(bisect_right(self.t, t) - 1, len(self.t) - 2)
        t0, t1 = self.t[i], self.t[i + 1]
        h = t1 - t0
        tau = t - t0
        w = self._w[i]
        wn = math.sqrt(w[0] ** 2 + w[1] ** 2 + w[2] ** 2)
        q = self._q[i]
        if wn > 0:
            q = quat_mul(q, quat_axis_angle((w[0] / wn, w[1] / wn, w[2] / wn), wn * tau))  # type: ignore[arg-type]  # four columns of the truth CSV: a quaternion of four
        rot = quat_matrix(q)  # type: ignore[arg-type]  # four columns of the truth CSV: a quaternion of four
        s = tau / h
        s2, s3 = s * s, s * s * s
        c = (2 * s3 - 3 * s2 + 1, (s3 - 2 * s2 + s) * h, -2 * s3 + 3 * s2, (s3 - s2) * h)
        d = ((6 * s2 - 6 * s) / h, 3 * s2 - 4 * s + 1, (-6 * s2 + 6 * s) / h, 3 * s2 - 2 * s)
        e = ((12 * s - 6) / h / h, (6 * s - 4) / h, (-12 * s + 6) / h / h, (6 * s - 2) / h)
        p0, v0, p1, v1 = self._p[i], self._v[i], self._p[i + 1], self._v[i + 1]
        pos = tuple(c[0] * p0[k] + c[1] * v0[k] + c[2] * p1[k] + c[3] * v1[k] for k in range(3))
        vel = tuple(d[0] * p0[k] + d[1] * v0[k] + d[2] * p1[k] + d[3] * v1[k] for k in range(3))
        acc = tuple(e[0] * p0[k] + e[1] * v0[k] + e[2] * p1[k] + e[3] * v1[k] for k in range(3))
        f = mat_t_vec(rot, (acc[0], acc[1], acc[2] - self.gravity_m_s2))
        return Kinematics(t, q, rot, w, f, acc, pos, vel)  # type: ignore[arg-type]  # three- and four-element columns of the truth CSV, sized when read

    def _extrapolated(self, t: float, i: int, interval: int) -> Kinematics:
        """Outside the record: the end sample's attitude turning at its interval's body rate,
        its position moving at its velocity, no acceleration. A truth file written by
        ``imuhal run --truth`` starts at the first estimate, after t = 0, where a run starts."""
        tau = t - self.t[i]
        w = self._w[interval]
        wn = math.sqrt(w[0] ** 2 + w[1] ** 2 + w[2] ** 2)
        q = self._q[i]
        if wn > 0:
            q = quat_mul(q, quat_axis_angle((w[0] / wn, w[1] / wn, w[2] / wn), wn * tau))  # type: ignore[arg-type]  # four columns of the truth CSV: a quaternion of four
        rot = quat_matrix(q)  # type: ignore[arg-type]  # four columns of the truth CSV: a quaternion of four
        p, v = self._p[i], self._v[i]
        pos = (p[0] + v[0] * tau, p[1] + v[1] * tau, p[2] + v[2] * tau)
        f = mat_t_vec(rot, (0.0, 0.0, -self.gravity_m_s2))
        return Kinematics(t, q, rot, w, f, (0.0, 0.0, 0.0), pos, v)  # type: ignore[arg-type]  # three- and four-element columns of the truth CSV, sized when read

    @classmethod
    def from_truth_csv(cls, path: str, *, gravity_m_s2: float = STANDARD_GRAVITY_M_S2,
                       use_velocity: bool = True) -> RecordedMotion:
        """From a truth CSV (docs/simulation.md); only time, quaternion, position and
        (optionally) velocity columns are used."""
        cols, _ = read_truth_csv(path)
        missing = [c for c in ("t_s", "qw", "qx", "qy", "qz", "pn_m", "pe_m", "pd_m")
                   if c not in cols]
        if missing:
            raise ValueError(f"{path}: truth CSV lacks columns {missing}")
        vel = None
        if use_velocity and all(c in cols for c in ("vn_m_s", "ve_m_s", "vd_m_s")):
            vel = np.column_stack([cols["vn_m_s"], cols["ve_m_s"], cols["vd_m_s"]])
        return cls(cols["t_s"], np.column_stack([cols[c] for c in ("qw", "qx", "qy", "qz")]),
                   np.column_stack([cols["pn_m"], cols["pe_m"], cols["pd_m"]]), vel,
                   gravity_m_s2=gravity_m_s2)


class ReplayParams(WorldParams):
    path: str
    """A truth CSV (docs/simulation.md) whose attitude and position are replayed."""
    use_velocity: bool = True
    """Use the file's velocity columns; False: estimate them from positions."""


class ReplayScenario(MotionScenario):
    """Replays a recorded trajectory; pressure, temperature and field come from the
    environment (so a recording can be flown again in other weather or at another site)."""

    name: ClassVar[str] = "replay"
    description: ClassVar[str] = "a recorded truth CSV replayed (times as in the file)"
    Params = ReplayParams
    default_duration_s: ClassVar[float] = 0.0

    def __init__(self, params: Any = None, *, seed: int = 0) -> None:
        if params is None:
            raise ValueError("the replay scenario needs params={'path': <truth CSV>}")
        super().__init__(params, seed=seed)

    def build_motion(self) -> Motion:
        p: ReplayParams = self.params  # type: ignore[assignment]  # the scenario's own Params model: Scenario types params as the base class
        return RecordedMotion.from_truth_csv(p.path, gravity_m_s2=p.environment.gravity_m_s2,
                                             use_velocity=p.use_velocity)

    @property
    def duration_s(self) -> float:
        assert isinstance(self.motion, RecordedMotion)
        return self.motion.span_s[1]
