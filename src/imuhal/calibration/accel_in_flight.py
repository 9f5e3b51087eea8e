"""The accelerometer's offset learned in flight, from GNSS velocity and the barometer.

Why a filter of its own: an AHRS levels its attitude on the accelerometer, so a horizontal
offset b becomes a tilt error of b / g that makes the offset vanish from every comparison
made with the AHRS's attitude (on the uncalibrated seed-gps-vario in ``thermal``, a least
squares fit of the GNSS velocity increments against the AHRS attitude finds a tenth of the
offset, against the true attitude all of it). This learner therefore keeps its own attitude,
integrated from the gyro and corrected by the velocity only, never by the direction of the
specific force: a loosely coupled GNSS/INS error-state Kalman filter whose states are

- ``phi`` (3): the rotation (rad, NED) that takes the learner's attitude to the true one;
- ``dv`` (3): the velocity error (m/s, NED);
- ``db`` (3): the accelerometer offset error (m/s^2, body frame): what the samples fed
  still carry;
- ``dd`` (1): the down position error (m) against the barometer's altitude;
- ``lag`` (1): how late (s) the GNSS velocity's time stamps are. A receiver's velocity is
  stamped when its message arrives less the latency its driver states; a stamp late by
  ``lag`` reads ``v(t - lag) = v(t) - lag a(t)``, which in a turn (a = 3 m/s^2 at 10 m/s
  in a 20 s circle) looks like a tilt. It is observable from that acceleration.

The velocity error grows as ``dv' = -[f_n]x phi - R db`` (f_n the specific force in NED,
R body to NED) and the down position as ``dd' = dv_down``; phi and db are random walks. An
offset and a tilt both push the velocity the same way while the board holds its heading;
they separate when the heading turns (the offset turns with the body, a tilt error does
not) and when the specific force changes its direction in the body (the launch's run-up,
entering a turn). Over a GNSS interval the transition is exact to first order in the
sample period: the per-sample terms are summed (:meth:`_accumulate`) and the 10 x 10
covariance is propagated once per measurement.

Measurements: the GNSS velocity (NED, noise: the receiver's speed accuracy, never below
``gnss_velocity_noise_m_s``) observes every axis once the board manoeuvres; the barometer's
pressure altitude observes the down position and through it the vertical offset in every
board (without GNSS only the body axis that points down is learned: ``dv_down`` does not
see a tilt to first order, and the horizontal states keep their prior).

The attitude is taken once from the AHRS (its first estimate once a velocity or pressure is
known) with the prior uncertainty of a tilt the offset may cause; after that the learner
never looks at the AHRS again.

**Convergence criterion**: after at least ``min_updates`` measurements, a body axis is
learned once the standard deviation of its offset is at most ``max_std_mg``
(:class:`~imuhal.calibration.model.AccelInFlightSettings`); the learner has converged when
every axis is. A learned axis is applied to the device's samples at once (the AHRS and the
vario get corrected samples) and again whenever its value moves by a tenth of the criterion;
an axis the motion does not determine (the horizontal ones without GNSS) is never applied.
"""

from __future__ import annotations

import math
from datetime import datetime

import numpy as np

from imuhal.calibration.model import (
    AccelCalibration,
    AccelInFlightSettings,
    CalibrationBinding,
    Vec3,
)
from imuhal.core.atmosphere import STANDARD_GRAVITY_M_S2, altitude_m_from_pressure

PROCEDURE = "accel-in-flight"
G_M_S2 = STANDARD_GRAVITY_M_S2
MG = G_M_S2 / 1000.0
_NS = 1e-9
_MAX_GAP_S = 0.1
"""A gap between two gyro or two accelerometer samples longer than this is not integrated
over (a lost stretch); the covariance still grows over it through the process noise."""
_PHI, _V, _B, _D, _LAG = slice(0, 3), slice(3, 6), slice(6, 9), 9, 10
_N = 11
_ACCEL_TAU_S = 0.1
"""Time constant (s) of the smoothed NED acceleration the lag state multiplies."""


Quat = tuple[float, float, float, float]


def _skew(v: np.ndarray) -> np.ndarray:
    return np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])


def _rot(q: Quat) -> tuple[tuple[float, ...], ...]:
    """Body to NED rotation matrix of the unit quaternion (w, x, y, z), as rows."""
    w, x, y, z = q
    return ((1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)),
            (2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)),
            (2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)))


def _rotation(x: float, y: float, z: float) -> Quat:
    """The unit quaternion of the rotation vector (x, y, z) (rad); not zero."""
    angle = math.sqrt(x * x + y * y + z * z)
    s = math.sin(0.5 * angle) / angle
    return (math.cos(0.5 * angle), x * s, y * s, z * s)


def _unit_product(a: Quat, b: Quat) -> Quat:
    """a (x) b, normalised (the rounding of many products would grow its length)."""
    w1, x1, y1, z1 = a
    w2, x2, y2, z2 = b
    w = w1 * w2 - x1 * x2 - y1 * y2 - z1 * z2
    x = w1 * x2 + x1 * w2 + y1 * z2 - z1 * y2
    y = w1 * y2 - x1 * z2 + y1 * w2 + z1 * x2
    z = w1 * z2 + x1 * y2 - y1 * x2 + z1 * w2
    k = 1.0 / math.sqrt(w * w + x * x + y * y + z * z)
    return (w * k, x * k, y * k, z * k)


class AccelOffsetLearner:
    """Push-style: :meth:`gyro` and :meth:`accel` with each body-frame sample as the AHRS
    gets it, :meth:`attitude` with the AHRS's estimates (used once, to start), and
    :meth:`velocity` / :meth:`pressure` with the aiding measurements. :attr:`converged`
    once the criterion holds; :meth:`offset_body_m_s2` is then what to subtract."""

    def __init__(self, settings: AccelInFlightSettings | None = None, *,
                 prior_offset_m_s2: float = 60 * G_M_S2 / 1000.0) -> None:
        """``prior_offset_m_s2``: the offset's standard deviation before flight, per axis
        (the chip's specified offset; the setting's ``initial_offset_mg`` overrides it)."""
        self.settings = settings or AccelInFlightSettings()
        s = self.settings
        self.prior_offset_m_s2 = prior_offset_m_s2 if s.initial_offset_mg is None \
            else s.initial_offset_mg * MG
        self.q: Quat | None = None
        """The learner's own attitude (body to NED), None before it started."""
        self.v_ned = np.zeros(3)
        self.down_m = 0.0
        self.offset_m_s2 = np.zeros(3)
        """The learned offset (body frame, m/s^2): the whole offset, what is applied and
        what is still being corrected."""
        self.applied_m_s2 = np.zeros(3)
        """The part of the offset already subtracted from the samples fed (applied by the
        pipeline through the device's calibration)."""
        self.p = np.zeros((_N, _N))
        self.lag_s = 0.0
        """How late the GNSS velocity stamps are (s), learned."""
        self._a_ned = [0.0, 0.0, 0.0]
        self._turned_rad = 0.0
        self.updates = 0
        self.learned_axes = [False, False, False]
        """Per body axis: its offset met the criterion (and is applied)."""
        self._candidate_q: Quat | None = None
        self._t_gyro: int | None = None
        self._t_accel: int | None = None
        self._t_prop: int | None = None
        self._t_baro: int | None = None
        self._reset_sums()
        self.latest: dict[str, object] = self.status()
        """:meth:`status` as of the last update: what another thread (the live view) reads,
        replaced whole."""

    # -- the nominal state, sample by sample --------------------------------------------

    def _reset_sums(self) -> None:
        self._sf = [0.0, 0.0, 0.0]          # sum f_n dt
        self._sr = [0.0] * 9                # sum R dt (rows)
        self._tf = [0.0, 0.0, 0.0]          # sum (t - t0) f_n dt
        self._tr = [0.0] * 9                # sum (t - t0) R dt

    def attitude(self, q_body_to_ned: Quat) -> None:
        """The AHRS's attitude: kept as the starting attitude until an aiding measurement
        starts the learner; ignored after."""
        if self.q is None:
            self._candidate_q = tuple(float(v) for v in q_body_to_ned)  # type: ignore[assignment]  # four floats from a four-tuple

    def gyro(self, t_ns: int, gyro_rad_s: Vec3) -> None:
        """Integrate the learner's attitude over the gyro sample (body frame, rad/s)."""
        last, self._t_gyro = self._t_gyro, t_ns
        if self.q is None or last is None:
            return
        dt = (t_ns - last) * _NS
        if not 0.0 < dt <= _MAX_GAP_S:
            return
        wx, wy, wz = gyro_rad_s
        n = math.sqrt(wx * wx + wy * wy + wz * wz)
        if n * dt < 1e-12:
            return
        # the body turned by omega dt in its own axes: q (x) exp(omega dt)
        self.q = _unit_product(self.q, _rotation(wx * dt, wy * dt, wz * dt))
        self._turned_rad += n * dt

    def accel(self, t_ns: int, accel_m_s2: Vec3) -> None:
        """Integrate the velocity and down position over the accelerometer sample (body
        frame, m/s^2, with ``applied_m_s2`` already subtracted by the pipeline)."""
        last, self._t_accel = self._t_accel, t_ns
        if self.q is None or last is None or self._t_prop is None:
            return
        dt = (t_ns - last) * _NS
        if not 0.0 < dt <= _MAX_GAP_S:
            return
        extra = self.applied_m_s2 - self.offset_m_s2
        fx, fy, fz = (accel_m_s2[0] + float(extra[0]), accel_m_s2[1] + float(extra[1]),
                      accel_m_s2[2] + float(extra[2]))
        r = _rot(self.q)
        fn = (r[0][0] * fx + r[0][1] * fy + r[0][2] * fz,
              r[1][0] * fx + r[1][1] * fy + r[1][2] * fz,
              r[2][0] * fx + r[2][1] * fy + r[2][2] * fz)
        vd = self.v_ned[2]
        self.v_ned += (fn[0] * dt, fn[1] * dt, (fn[2] + G_M_S2) * dt)
        k = min(dt / _ACCEL_TAU_S, 1.0)
        a = self._a_ned
        a[0] += k * (fn[0] - a[0])
        a[1] += k * (fn[1] - a[1])
        a[2] += k * (fn[2] + G_M_S2 - a[2])
        self.down_m += 0.5 * (vd + self.v_ned[2]) * dt
        tau = (t_ns - self._t_prop) * _NS
        for i in range(3):
            self._sf[i] += fn[i] * dt
            self._tf[i] += tau * fn[i] * dt
            for j in range(3):
                self._sr[3 * i + j] += r[i][j] * dt
                self._tr[3 * i + j] += tau * r[i][j] * dt

    # -- measurements ---------------------------------------------------------------------

    def velocity(self, t_ns: int, velocity_ned_m_s: Vec3, accuracy_m_s: float | None) -> bool:
        """Fuse a GNSS velocity (NED, m/s); True when the applied offset should change."""
        v = np.asarray(velocity_ned_m_s, dtype=float)
        if self.q is None:
            return self._start(t_ns, v, None)
        sigma = max(accuracy_m_s or 0.0, self.settings.gnss_velocity_noise_m_s)
        self._propagate(t_ns)
        h = np.zeros((3, _N))
        h[:, _V] = np.eye(3)
        a = np.array(self._a_ned)
        h[:, _LAG] = -a
        predicted = self.v_ned - self.lag_s * a
        return self._update(h, v - predicted, np.eye(3) * sigma * sigma)

    def pressure(self, t_ns: int, pressure_pa: float) -> bool:
        """Fuse a barometer reading (Pa) as a down position, at most every
        ``baro_interval_s``; True when the applied offset should change."""
        down = -altitude_m_from_pressure(pressure_pa)
        if self.q is None:
            return self._start(t_ns, None, down)
        if self._t_baro is not None and (t_ns - self._t_baro) * _NS \
                < self.settings.baro_interval_s:
            return False
        self._t_baro = t_ns
        self._propagate(t_ns)
        h = np.zeros((1, _N))
        h[0, _D] = 1.0
        sigma = self.settings.baro_noise_m
        return self._update(h, np.array([down - self.down_m]), np.array([[sigma * sigma]]))

    def _start(self, t_ns: int, v: np.ndarray | None, down: float | None) -> bool:
        """Start from the AHRS's attitude and the first aiding measurement."""
        if self._candidate_q is None or (v is None and down is None):
            return False
        s = self.settings
        self.q = self._candidate_q
        self.v_ned = v.copy() if v is not None else np.zeros(3)
        self.down_m = down if down is not None else 0.0
        self._t_baro = t_ns if down is not None else None
        self._t_prop = t_ns
        b0 = self.prior_offset_m_s2
        tilt0 = math.hypot(b0 / G_M_S2, math.radians(s.initial_tilt_deg))
        var = [tilt0 ** 2, tilt0 ** 2, math.radians(s.initial_heading_deg) ** 2]
        var += [s.gnss_velocity_noise_m_s ** 2 if v is not None else 100.0] * 2
        var += [s.gnss_velocity_noise_m_s ** 2 if v is not None else 1.0]
        var += [b0 * b0] * 3 + [s.baro_noise_m ** 2 if down is not None else 1e4]
        var += [s.initial_lag_s ** 2]
        self.p = np.diag(var)
        self._turned_rad = 0.0
        self._reset_sums()
        return False

    def _propagate(self, t_ns: int) -> None:
        """The covariance from the last measurement to ``t_ns``, from the summed terms."""
        assert self._t_prop is not None
        span = max((t_ns - self._t_prop) * _NS, 0.0)
        sf = np.array(self._sf)
        sr = np.array(self._sr).reshape(3, 3)
        g = np.hstack([-_skew(sf), -sr])                    # dv over the span per (phi, db)
        gt = span * g - np.hstack([-_skew(np.array(self._tf)),
                                   -np.array(self._tr).reshape(3, 3)])
        phi = np.eye(_N)
        cols = np.r_[0:3, 6:9]
        phi[3:6, cols] = g
        phi[_D, 5] = span
        phi[_D, cols] = gt[2]
        s = self.settings
        q = np.zeros(_N)
        # the gyro's noise, and its scale error over the angle turned since the last step
        q[_PHI] = s.attitude_random_walk_rad_sqrt_s ** 2 * span \
            + (s.gyro_scale_error * self._turned_rad) ** 2
        self._turned_rad = 0.0
        q[_V] = s.velocity_random_walk_m_s_sqrt_s ** 2 * span
        q[_B] = (s.offset_random_walk_mg_sqrt_s * MG) ** 2 * span
        q[_D] = (s.velocity_random_walk_m_s_sqrt_s ** 2) * span ** 3 / 3.0
        self.p = phi @ self.p @ phi.T + np.diag(q)
        self._t_prop = t_ns
        self._reset_sums()

    def _update(self, h: np.ndarray, z: np.ndarray, r: np.ndarray) -> bool:
        """One Kalman update and the reset of the error state into the nominal one."""
        s = h @ self.p @ h.T + r
        k = self.p @ h.T @ np.linalg.inv(s)
        x = k @ z
        i_kh = np.eye(_N) - k @ h
        self.p = i_kh @ self.p @ i_kh.T + k @ r @ k.T   # Joseph form: stays symmetric
        self._correct(x)
        self.updates += 1
        limit = self.settings.max_std_mg
        new = False
        if self.updates >= self.settings.min_updates:
            for i, std in enumerate(self.std_mg()):
                if not self.learned_axes[i] and std <= limit:
                    self.learned_axes[i] = new = True
        if self.updates % 5 == 0 or new:
            self.latest = self.status()
        # a learned axis is applied at once, then again as it moves by a tenth of the
        # criterion (the fit keeps improving without re-applying at every measurement)
        moved = max((abs(float(self.offset_m_s2[i] - self.applied_m_s2[i])) / MG
                     for i in range(3) if self.learned_axes[i]), default=0.0)
        return new or moved >= 0.1 * limit

    @property
    def converged(self) -> bool:
        """Every body axis learned."""
        return all(self.learned_axes)

    def _correct(self, x: np.ndarray) -> None:
        assert self.q is not None
        phi = x[_PHI]
        if float(np.linalg.norm(phi)) > 0.0:
            # the correction acts in NED: q_true = exp(phi) (x) q
            self.q = _unit_product(_rotation(float(phi[0]), float(phi[1]), float(phi[2])),
                                   self.q)
        self.v_ned += x[_V]
        self.offset_m_s2 += x[_B]
        self.down_m += float(x[_D])
        self.lag_s += float(x[_LAG])

    # -- what the run shows and saves -----------------------------------------------------

    def mark_applied(self) -> Vec3:
        """The learned axes' offset, which the pipeline subtracts from the samples from now
        on (body frame, m/s^2; 0 on an axis not learned)."""
        self.applied_m_s2 = np.where(self.learned_axes, self.offset_m_s2, 0.0)
        self.latest = self.status()
        b = self.applied_m_s2
        return (float(b[0]), float(b[1]), float(b[2]))

    def offset_body_m_s2(self) -> Vec3:
        """The offset learned so far (body frame, m/s^2), applied or not."""
        b = self.offset_m_s2
        return (float(b[0]), float(b[1]), float(b[2]))

    def std_mg(self) -> Vec3:
        """The learned offset's standard deviation per body axis (mg)."""
        d = np.sqrt(np.clip(np.diag(self.p)[_B], 0.0, None)) / MG
        return (float(d[0]), float(d[1]), float(d[2]))

    def status(self) -> dict[str, object]:
        """What the run's health shows: the measurements fused, the offset so far (body
        frame, mg) and its uncertainty, whether it is applied, and the criterion."""
        started = self.q is not None
        return {"quantity": "accel", "updates": self.updates, "converged": self.converged,
                "learned_axes": tuple(self.learned_axes),
                "gnss_lag_s": round(self.lag_s, 3) if started else None,
                "offset_mg": tuple(round(v / MG, 2) for v in self.offset_body_m_s2())
                if started else None,
                "std_mg": tuple(round(v, 2) for v in self.std_mg()) if started else None,
                "criterion": {"min_updates": self.settings.min_updates,
                              "max_std_mg": self.settings.max_std_mg}}

    def record(self, chip_to_body: list[list[float]], *,
               binding: CalibrationBinding | None = None,
               date: datetime | None = None) -> AccelCalibration:
        """The applied offset as an accelerometer record (sensor frame: the body-frame
        offset rotated back through ``chip_to_body``; scale 1), with its quality figures."""
        c = np.asarray(chip_to_body, dtype=float)
        o = c.T @ self.applied_m_s2
        std = self.std_mg()
        quality = {"updates": float(self.updates), "std_x_mg": std[0], "std_y_mg": std[1],
                   "std_z_mg": std[2]}
        return AccelCalibration(offset_m_s2=(float(o[0]), float(o[1]), float(o[2])),
                                procedure=PROCEDURE, binding=binding, date=date,
                                quality=quality)
