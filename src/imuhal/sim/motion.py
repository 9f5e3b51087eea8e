"""Rigid-body trajectories: attitude, angular rate, specific force, position and velocity.

Frames: earth NED; body FRD (x forward, y right, z down). Quaternions scalar first, rotating
body -> NED (``v_ned = R(q) v_body``). Specific force is ``R^T (a_ned - g_ned)`` with
``g_ned = (0, 0, +g)``: level at rest it reads (0, 0, -g).

Everything is a pure function of time. Kinematic consistency holds by construction:

* attitude is a product of rotations whose angles are :class:`~imuhal.sim.signals.Signal`s,
  and the body rate is the exact derivative of that product;
* velocity and acceleration come from signals with exact derivatives; where position has
  no closed form (flight along a turning heading or along the nose) it is the integral of
  the velocity on a fine grid (cubic Hermite quadrature using the exact acceleration,
  error below a micrometre), filled lazily and deterministically.

Hot paths use plain floats and tuples: these are evaluated at every sensor poll.
"""

from __future__ import annotations

import math
from abc import ABC, abstractmethod
from collections import OrderedDict
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from imuhal.core.atmosphere import STANDARD_GRAVITY_M_S2
from imuhal.sim.signals import Signal

Vec3 = tuple[float, float, float]
Quat = tuple[float, float, float, float]
Mat3 = tuple[float, float, float, float, float, float, float, float, float]
"""A 3x3 matrix as a row-major 9-tuple."""
Triple = tuple[float, float, float]
"""A signal's (value, first derivative, second derivative)."""

_SEGMENT = 1024
"""Quadrature nodes per segment of the position table (10.24 s at the default 0.01 s)."""
_SEGMENTS_KEPT = 4
"""Segments kept computed: the current one and a few recently queried (truth lookups)."""
_IDENTITY_MAT: Mat3 = (1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0)

KinematicsFields = tuple[float, Quat, Mat3, Vec3, Vec3, Vec3, Vec3, Vec3]
"""The fields of :class:`Kinematics`, in order, as a plain tuple."""


@dataclass(frozen=True, slots=True)
class Kinematics:
    """The rigid-body state at ``t_s``. SI units; see the module docstring for frames."""

    t_s: float
    q_body_to_ned: Quat
    rotation: Mat3
    """R(q) row-major: v_ned = R v_body."""
    angular_rate_body_rad_s: Vec3
    specific_force_body_m_s2: Vec3
    acceleration_ned_m_s2: Vec3
    position_ned_m: Vec3
    velocity_ned_m_s: Vec3


# --------------------------------------------------------------------------- float helpers
def quat_mul(p: Quat, q: Quat) -> Quat:
    """Hamilton product p * q on tuples."""
    pw, px, py, pz = p
    qw, qx, qy, qz = q
    return (pw * qw - px * qx - py * qy - pz * qz,
            pw * qx + px * qw + py * qz - pz * qy,
            pw * qy - px * qz + py * qw + pz * qx,
            pw * qz + px * qy - py * qx + pz * qw)


def quat_matrix(q: Quat) -> Mat3:
    w, x, y, z = q
    return (w * w + x * x - y * y - z * z, 2 * (x * y - w * z), 2 * (x * z + w * y),
            2 * (x * y + w * z), w * w - x * x + y * y - z * z, 2 * (y * z - w * x),
            2 * (x * z - w * y), 2 * (y * z + w * x), w * w - x * x - y * y + z * z)


def mat_vec(m: Mat3, v: Vec3) -> Vec3:
    return (m[0] * v[0] + m[1] * v[1] + m[2] * v[2],
            m[3] * v[0] + m[4] * v[1] + m[5] * v[2],
            m[6] * v[0] + m[7] * v[1] + m[8] * v[2])


def mat_t_vec(m: Mat3, v: Vec3) -> Vec3:
    """R^T v (NED -> body for a body -> NED rotation)."""
    return (m[0] * v[0] + m[3] * v[1] + m[6] * v[2],
            m[1] * v[0] + m[4] * v[1] + m[7] * v[2],
            m[2] * v[0] + m[5] * v[1] + m[8] * v[2])


def quat_axis_angle(axis: Vec3, angle: float) -> Quat:
    h = 0.5 * angle
    s = math.sin(h)
    return (math.cos(h), axis[0] * s, axis[1] * s, axis[2] * s)


def quat_euler(roll: float, pitch: float, yaw: float) -> Quat:
    """Body -> NED quaternion from ZYX Euler angles in radians (any range)."""
    cr, sr = math.cos(0.5 * roll), math.sin(0.5 * roll)
    cp, sp = math.cos(0.5 * pitch), math.sin(0.5 * pitch)
    cy, sy = math.cos(0.5 * yaw), math.sin(0.5 * yaw)
    return (cy * cp * cr + sy * sp * sr, cy * cp * sr - sy * sp * cr,
            cy * sp * cr + sy * cp * sr, sy * cp * cr - cy * sp * sr)


def euler_body_rate(roll: float, pitch: float, droll: float, dpitch: float,
                    dyaw: float) -> Vec3:
    """Body angular rate (p, q, r) of ZYX Euler angles changing at the given rates.

    Exact for any angles (no division, so no singularity at pitch +-90 deg).
    """
    sr, cr = math.sin(roll), math.cos(roll)
    sp, cp = math.sin(pitch), math.cos(pitch)
    return (droll - dyaw * sp,
            dpitch * cr + dyaw * sr * cp,
            -dpitch * sr + dyaw * cr * cp)


def _unit(v: Sequence[float]) -> Vec3:
    n = math.sqrt(sum(c * c for c in v))
    if n == 0 or not math.isfinite(n):
        raise ValueError(f"rotation axis {tuple(v)} has no direction")
    return (v[0] / n, v[1] / n, v[2] / n)


@dataclass(frozen=True, slots=True)
class KinematicsMany:
    """:class:`Kinematics` at many times: each component an array over the times
    (``rotation`` row-major, nine arrays); no acceleration (the chips do not measure it)."""

    q_body_to_ned: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]
    rotation: tuple[np.ndarray, ...]
    angular_rate_body_rad_s: tuple[np.ndarray, np.ndarray, np.ndarray]
    specific_force_body_m_s2: tuple[np.ndarray, np.ndarray, np.ndarray]
    position_ned_m: tuple[np.ndarray, np.ndarray, np.ndarray]
    velocity_ned_m_s: tuple[np.ndarray, np.ndarray, np.ndarray]


def _quat_euler_many(roll: np.ndarray, pitch: np.ndarray, yaw: np.ndarray
                     ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """:func:`quat_euler` on arrays (the same operations)."""
    cr, sr = np.cos(0.5 * roll), np.sin(0.5 * roll)
    cp, sp = np.cos(0.5 * pitch), np.sin(0.5 * pitch)
    cy, sy = np.cos(0.5 * yaw), np.sin(0.5 * yaw)
    return (cy * cp * cr + sy * sp * sr, cy * cp * sr - sy * sp * cr,
            cy * sp * cr + sy * cp * sr, sy * cp * cr - cy * sp * sr)


def _euler_body_rate_many(roll: np.ndarray, pitch: np.ndarray, droll: np.ndarray,
                          dpitch: np.ndarray, dyaw: np.ndarray
                          ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """:func:`euler_body_rate` on arrays (the same operations)."""
    sr, cr = np.sin(roll), np.cos(roll)
    sp, cp = np.sin(pitch), np.cos(pitch)
    return (droll - dyaw * sp, dpitch * cr + dyaw * sr * cp, -dpitch * sr + dyaw * cr * cp)


# --------------------------------------------------------------------------- motions
class Motion(ABC):
    """A trajectory: ``kinematics(t_s)`` for any ``t_s >= 0``; pure function of time."""

    gravity_m_s2: float = STANDARD_GRAVITY_M_S2

    @abstractmethod
    def kinematics(self, t_s: float) -> Kinematics:
        """The state at ``t_s`` (s since the start)."""

    def position_ned(self, t_s: float) -> Vec3:
        """``kinematics(t_s).position_ned_m`` alone (a subclass may compute it for less)."""
        return self.kinematics(t_s).position_ned_m

    def kinematics_fields(self, t_s: float) -> KinematicsFields:
        """The fields of ``kinematics(t_s)`` in order, as a plain tuple (a subclass may
        build them without the dataclass, for the per-poll path)."""
        k = self.kinematics(t_s)
        return (k.t_s, k.q_body_to_ned, k.rotation, k.angular_rate_body_rad_s,
                k.specific_force_body_m_s2, k.acceleration_ned_m_s2, k.position_ned_m,
                k.velocity_ned_m_s)


@dataclass(frozen=True, slots=True)
class BodyRotation:
    """A rotation about a fixed body axis by a time-varying angle (rad), applied after the
    Euler attitude (and after earlier body rotations): R = R_euler * R_1 * R_2 ..."""

    axis: Vec3
    angle: Signal


class FlightMotion(Motion):
    """A trajectory composed from signals.

    Attitude: ``R = Rz(yaw) Ry(pitch) Rx(roll + bank) * R_1(a_1) * R_2(a_2) ...`` where the
    optional ``bank`` is the coordinated-turn bank ``atan(V * dyaw/dt / g)`` for the speed V
    of ``speed_along_heading`` (or ``speed_along_nose``), and each ``R_i`` is a
    :class:`BodyRotation` (tumbling, figure-of-8 moves).

    Velocity (NED) is the sum of
      * ``north``/``east``/``down`` position signals (closed-form position),
      * ``speed_along_heading``: horizontal speed along the yaw direction (a glider),
      * ``speed_along_nose``: speed along body x (an aeroplane with no angle of attack or
        sideslip; a = R (dV/dt, V r, -V q) in closed form),
      * a constant ``wind_ned_m_s`` drift.

    ``grid_step_s`` is the quadrature step for the positions without closed form.
    """

    def __init__(self, *, yaw: Signal | None = None, pitch: Signal | None = None,
                 roll: Signal | None = None, body_rotations: Sequence[BodyRotation] = (),
                 coordinated_bank: bool = False, north: Signal | None = None,
                 east: Signal | None = None, down: Signal | None = None,
                 speed_along_heading: Signal | None = None,
                 speed_along_nose: Signal | None = None,
                 wind_ned_m_s: Vec3 = (0.0, 0.0, 0.0),
                 gravity_m_s2: float = STANDARD_GRAVITY_M_S2,
                 grid_step_s: float = 0.01) -> None:
        self.yaw = yaw or Signal()
        self.pitch = pitch or Signal()
        self.roll = roll or Signal()
        self.body_rotations = tuple(BodyRotation(_unit(b.axis), b.angle)
                                    for b in body_rotations)
        self.coordinated_bank = coordinated_bank
        self.north, self.east, self.down = north, east, down
        self.speed_along_heading = speed_along_heading
        self.speed_along_nose = speed_along_nose
        if coordinated_bank and speed_along_heading is None and speed_along_nose is None:
            raise ValueError("coordinated_bank needs a speed signal to bank for")
        self.wind = (float(wind_ned_m_s[0]), float(wind_ned_m_s[1]), float(wind_ned_m_s[2]))
        self.gravity_m_s2 = float(gravity_m_s2)
        self.grid_step_s = float(grid_step_s)
        self._tabulated = speed_along_heading is not None or speed_along_nose is not None
        # Quadrature table of the tabulated velocity (node k at t = k * h), kept bounded: the
        # state (v, a, p) at the start of every segment of _SEGMENT nodes is kept for the
        # whole run (a few bytes per 10 s), the nodes themselves only for the last few
        # segments used; an older segment is recomputed from its start, to the same floats.
        self._starts: list[tuple[Vec3, Vec3, Vec3]] = []
        self._segments: OrderedDict[int, tuple[list[Vec3], list[Vec3], list[Vec3]]] = \
            OrderedDict()
        self._segment_arrays_kept: dict[int, tuple[object, tuple[np.ndarray, np.ndarray,
                                                                 np.ndarray]]] = {}
        """The segments kept, as arrays for :meth:`kinematics_many` (made on demand)."""

    # ------------------------------------------------------------------ attitude + velocity
    def _speeds(self, t: float) -> tuple[Triple | None, Triple | None]:
        """(speed along the heading, speed along the nose) signals at ``t``, None if absent;
        evaluated once per time and shared by the bank and the tabulated velocity."""
        heading = self.speed_along_heading
        nose = self.speed_along_nose
        return (None if heading is None else heading(t), None if nose is None else nose(t))

    def _attitude(self, t: float, yaw: Triple, bank_speed: Triple | None) -> tuple[Quat, Vec3]:
        """Attitude and body rate at ``t`` given the yaw signal's state there and the speed
        the coordinated bank is computed for."""
        psi, dpsi, ddpsi = yaw
        th, dth = self.pitch.value_rate(t)
        ph, dph = self.roll.value_rate(t)
        if self.coordinated_bank:
            assert bank_speed is not None
            v, dv, _ = bank_speed
            x = v * dpsi / self.gravity_m_s2
            ph += math.atan(x)
            dph += (dv * dpsi + v * ddpsi) / self.gravity_m_s2 / (1.0 + x * x)
        q = quat_euler(ph, th, psi)
        w = euler_body_rate(ph, th, dph, dth, dpsi)
        if self.body_rotations:
            # R = R_e B_1 ... B_n; body rate = B^T w_e + sum_i (B_{i+1}..B_n)^T a_i da_i.
            acc_w = (0.0, 0.0, 0.0)
            right: Quat = (1.0, 0.0, 0.0, 0.0)
            for rot in reversed(self.body_rotations):
                ang, dang, _ = rot.angle(t)
                m = quat_matrix(right)
                ax = mat_t_vec(m, rot.axis)
                acc_w = (acc_w[0] + ax[0] * dang, acc_w[1] + ax[1] * dang,
                         acc_w[2] + ax[2] * dang)
                right = quat_mul(quat_axis_angle(rot.axis, ang), right)
            we = mat_t_vec(quat_matrix(right), w)
            w = (we[0] + acc_w[0], we[1] + acc_w[1], we[2] + acc_w[2])
            q = quat_mul(q, right)
        return q, w

    def _tab_velocity(self, yaw: Triple, heading: Triple | None, nose: Triple | None,
                      rot: Mat3, w: Vec3) -> tuple[Vec3, Vec3]:
        """Velocity and acceleration (NED) of the parts without closed-form position, from
        the states of the yaw and speed signals, the rotation and the body rate."""
        vn = ve = vd = an = ae = ad = 0.0
        if heading is not None:
            v, dv, _ = heading
            psi, dpsi, _ = yaw
            c, s = math.cos(psi), math.sin(psi)
            vn += v * c
            ve += v * s
            an += dv * c - v * dpsi * s
            ae += dv * s + v * dpsi * c
        if nose is not None:
            v, dv, _ = nose
            vn += v * rot[0]
            ve += v * rot[3]
            vd += v * rot[6]
            a = mat_vec(rot, (dv, v * w[2], -v * w[1]))
            an += a[0]
            ae += a[1]
            ad += a[2]
        return (vn, ve, vd), (an, ae, ad)

    # ------------------------------------------------------------------ position quadrature
    def _node(self, k: int) -> tuple[Vec3, Vec3]:
        t = k * self.grid_step_s
        yaw = self.yaw(t)
        heading, nose = self._speeds(t)
        if nose is None:
            # Along the heading only: the velocity needs neither the attitude nor the rate.
            return self._tab_velocity(yaw, heading, None, _IDENTITY_MAT, (0.0, 0.0, 0.0))
        q, w = self._attitude(t, yaw, heading if heading is not None else nose)
        return self._tab_velocity(yaw, heading, nose, quat_matrix(q), w)

    def _segment(self, index: int) -> tuple[list[Vec3], list[Vec3], list[Vec3]]:
        """Nodes ``index * _SEGMENT`` .. ``(index + 1) * _SEGMENT`` (inclusive): velocity,
        acceleration and position lists, computed from the segment's start state."""
        cached = self._segments.get(index)
        if cached is not None:
            self._segments.move_to_end(index)
            return cached
        if not self._starts:
            v, a = self._node(0)
            self._starts.append((v, a, (0.0, 0.0, 0.0)))
        while len(self._starts) <= index:  # segments before it first (their start states)
            self._segment(len(self._starts) - 1)
        h = self.grid_step_s
        v0, a0, p0 = self._starts[index]
        tv, ta, tp = [v0], [a0], [p0]
        first = index * _SEGMENT
        for k in range(first + 1, first + _SEGMENT + 1):
            v1, a1 = self._node(k)
            # Integral of the cubic Hermite interpolant of v (exact for cubic velocity).
            p1 = tuple(p0[i] + 0.5 * h * (v0[i] + v1[i]) + h * h / 12.0 * (a0[i] - a1[i])
                       for i in range(3))
            tv.append(v1)
            ta.append(a1)
            tp.append(p1)  # type: ignore[arg-type]  # a generator over range(3): three components
            v0, a0, p0 = v1, a1, p1  # type: ignore[assignment]  # a generator over range(3): three components
        if len(self._starts) == index + 1:
            self._starts.append((v0, a0, p0))
        self._segments[index] = (tv, ta, tp)
        if len(self._segments) > _SEGMENTS_KEPT:
            self._segments.popitem(last=False)
        return tv, ta, tp

    def _tab_position(self, t: float) -> Vec3:
        h = self.grid_step_s
        k = int(t / h)
        tv, ta, tp = self._segment(k // _SEGMENT)
        j = k % _SEGMENT
        s = t / h - k
        s2, s3, s4 = s * s, s * s * s, s * s * s * s
        i00 = s - s3 + 0.5 * s4
        i10 = 0.5 * s2 - 2.0 / 3.0 * s3 + 0.25 * s4
        i01 = s3 - 0.5 * s4
        i11 = -s3 / 3.0 + 0.25 * s4
        v0, a0, v1, a1, p0 = tv[j], ta[j], tv[j + 1], ta[j + 1], tp[j]
        return (p0[0] + h * (v0[0] * i00 + h * a0[0] * i10 + v1[0] * i01 + h * a1[0] * i11),
                p0[1] + h * (v0[1] * i00 + h * a0[1] * i10 + v1[1] * i01 + h * a1[1] * i11),
                p0[2] + h * (v0[2] * i00 + h * a0[2] * i10 + v1[2] * i01 + h * a1[2] * i11))

    # ------------------------------------------------------------------ many times at once
    def vectorised(self) -> bool:
        """True when :meth:`kinematics_many` covers this trajectory: no body rotations and
        no speed along the nose (those keep the per-time path)."""
        return not self.body_rotations and self.speed_along_nose is None

    def kinematics_many(self, t: np.ndarray) -> KinematicsMany:
        """:meth:`kinematics_fields` at every time of ``t`` (s, float64, >= 0) as arrays,
        by the same operations in the same order on numpy arrays (only for
        :meth:`vectorised` trajectories): what a chip's FIFO fill of n instants needs in one
        call instead of n."""
        if not self.vectorised():
            raise ValueError("kinematics_many covers no body rotations nor speed along the nose")
        t = np.asarray(t, dtype=float)
        if t.size and float(t.min()) < 0:
            raise ValueError(f"trajectories start at t = 0 s, got {float(t.min())}")
        psi, dpsi, ddpsi = self.yaw.many(t)
        th, dth, _ = self.pitch.many(t)
        ph, dph, _ = self.roll.many(t)
        heading = None if self.speed_along_heading is None else self.speed_along_heading.many(t)
        if self.coordinated_bank:
            assert heading is not None
            v, dv, _ = heading
            x = v * dpsi / self.gravity_m_s2
            # math.atan, not np.arctan: numpy's differs from it by an ulp at about one
            # argument in 600, and the bank is the only such call (sin and cos agree)
            ph = ph + np.fromiter(map(math.atan, x.tolist()), float, x.size)
            dph = dph + (dv * dpsi + v * ddpsi) / self.gravity_m_s2 / (1.0 + x * x)
        q = _quat_euler_many(ph, th, psi)
        w = _euler_body_rate_many(ph, th, dph, dth, dpsi)
        rot = quat_matrix(q)  # type: ignore[arg-type]  # the same expressions on arrays
        wn, we, wd = self.wind
        pos = [wn * t, we * t, wd * t]
        vel = [np.full_like(t, wn), np.full_like(t, we), np.full_like(t, wd)]
        acc = [np.zeros_like(t), np.zeros_like(t), np.zeros_like(t)]
        for axis, sig in enumerate((self.north, self.east, self.down)):
            if sig is not None:
                sp, sv, sa = sig.many(t)
                pos[axis], vel[axis], acc[axis] = pos[axis] + sp, vel[axis] + sv, acc[axis] + sa
        if heading is not None:
            v, dv, _ = heading
            c, sn = np.cos(psi), np.sin(psi)
            tv = (v * c, v * sn, np.zeros_like(t))
            ta = (dv * c - v * dpsi * sn, dv * sn + v * dpsi * c, np.zeros_like(t))
            tp = self._tab_position_many(t)
            # as the scalar path: tabulated parts added to the others, component by component
            for axis in range(3):
                pos[axis] = pos[axis] + tp[axis]
                vel[axis] = vel[axis] + (0.0 + tv[axis])
                acc[axis] = acc[axis] + (0.0 + ta[axis])
        f = mat_t_vec(rot, (acc[0], acc[1], acc[2] - self.gravity_m_s2))  # type: ignore[arg-type]  # arrays
        return KinematicsMany(q, rot, w, f, tuple(pos), tuple(vel))  # type: ignore[arg-type]  # arrays

    def _segment_arrays(self, index: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """:meth:`_segment`'s nodes as (3, nodes) arrays, kept beside the lists while the
        lists are (the same floats)."""
        lists = self._segment(index)
        cached = self._segment_arrays_kept.get(index)
        if cached is None or cached[0] is not lists:
            arrays = (np.array(lists[0]).T, np.array(lists[1]).T, np.array(lists[2]).T)
            cached = (lists, arrays)
            self._segment_arrays_kept[index] = cached
            for old in [i for i in self._segment_arrays_kept if i not in self._segments]:
                del self._segment_arrays_kept[old]
        return cached[1]

    def _tab_position_many(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """:meth:`_tab_position` at every time of ``t`` (the segments it needs filled as the
        scalar path fills them, so the same nodes)."""
        h = self.grid_step_s
        k = (t / h).astype(np.int64)  # int() of a non-negative float: truncation
        out = np.empty((3, t.size))
        segment = k // _SEGMENT
        for index in np.unique(segment).tolist():
            sel = segment == index
            tv, ta, tp = self._segment_arrays(index)
            ks = k[sel]
            j = ks % _SEGMENT
            v0, a0, p0, v1, a1 = tv[:, j], ta[:, j], tp[:, j], tv[:, j + 1], ta[:, j + 1]
            s = t[sel] / h - ks
            s2, s3, s4 = s * s, s * s * s, s * s * s * s
            i00 = s - s3 + 0.5 * s4
            i10 = 0.5 * s2 - 2.0 / 3.0 * s3 + 0.25 * s4
            i01 = s3 - 0.5 * s4
            i11 = -s3 / 3.0 + 0.25 * s4
            out[:, sel] = p0 + h * (v0 * i00 + h * a0 * i10 + v1 * i01 + h * a1 * i11)
        return out[0], out[1], out[2]

    # ------------------------------------------------------------------ public
    def position_ned(self, t_s: float) -> Vec3:
        """The position alone, without the attitude: the same operations as in
        :meth:`kinematics`, so the same floats (a barometer's truth needs only this)."""
        if t_s < 0:
            raise ValueError(f"trajectories start at t = 0 s, got {t_s}")
        t = float(t_s)
        wn, we, wd = self.wind
        pn, pe, pd = wn * t, we * t, wd * t
        if self.north is not None:
            pn = pn + self.north.value(t)
        if self.east is not None:
            pe = pe + self.east.value(t)
        if self.down is not None:
            pd = pd + self.down.value(t)
        if self._tabulated:
            tp = self._tab_position(t)
            pn, pe, pd = pn + tp[0], pe + tp[1], pd + tp[2]
        return (pn, pe, pd)

    def kinematics(self, t_s: float) -> Kinematics:
        return Kinematics(*self.kinematics_fields(t_s))

    def kinematics_fields(self, t_s: float) -> KinematicsFields:
        if t_s < 0:
            raise ValueError(f"trajectories start at t = 0 s, got {t_s}")
        t = float(t_s)
        yaw = self.yaw(t)
        heading, nose = self._speeds(t)
        q, w = self._attitude(t, yaw, heading if heading is not None else nose)
        rot = quat_matrix(q)
        wn, we, wd = self.wind
        pn, pe, pd = wn * t, we * t, wd * t
        vn, ve, vd = wn, we, wd
        an = ae = ad = 0.0
        if self.north is not None:
            p, v, a = self.north(t)
            pn, vn, an = pn + p, vn + v, an + a
        if self.east is not None:
            p, v, a = self.east(t)
            pe, ve, ae = pe + p, ve + v, ae + a
        if self.down is not None:
            p, v, a = self.down(t)
            pd, vd, ad = pd + p, vd + v, ad + a
        if self._tabulated:
            tv, ta = self._tab_velocity(yaw, heading, nose, rot, w)
            tp = self._tab_position(t)
            pn, pe, pd = pn + tp[0], pe + tp[1], pd + tp[2]
            vn, ve, vd = vn + tv[0], ve + tv[1], vd + tv[2]
            an, ae, ad = an + ta[0], ae + ta[1], ad + ta[2]
        f = mat_t_vec(rot, (an, ae, ad - self.gravity_m_s2))
        return (t, q, rot, w, f, (an, ae, ad), (pn, pe, pd), (vn, ve, vd))
