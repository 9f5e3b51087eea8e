"""Named coordinate conventions and exact conversions between them.

imuhal works internally in one convention, ``ned``: earth north-east-down, body
forward-right-down (FRD), accelerometer readings as specific force (a level board at rest
reads (0, 0, -9.81) m/s^2), quaternions rotating body -> earth. Data from elsewhere uses other
conventions; this module names them and converts vectors, quaternions and Euler angles
exactly (every axis change is a signed permutation, so no rounding beyond float64 products).

A convention is:

* an **earth frame**: three named directions (``north``, ``east``, ``up`` ...);
* **body axes**: three named directions of the board (``forward``, ``right``, ``up`` ...);
* an **accelerometer sign**: ``specific_force`` ("acceleration positive" in the Freescale
  note: the reading is f = a - g, so a level board at rest reads +1 g *up*) or
  ``gravity_positive`` (the reading is -f: a level board at rest reads +1 g *down*);
* an **Euler angle definition** (which rotations, in which order, with which ranges).

Both frames must be right-handed (proper rotations of NED/FRD, determinant +1); a mirror-image
frame is rejected when the convention is built. Angular rate and magnetic field are plain
vectors in the body axes (right-hand rule for rates); only the accelerometer has a sign
convention.

Named conventions (``CONVENTIONS``):

==========  =====================  =====================  ================  ===============
name        earth (x, y, z)        body (x, y, z)         accelerometer     Euler angles
==========  =====================  =====================  ================  ===============
ned         north, east, down      forward, right, down   specific force    aerospace ZYX
aerospace   north, east, down      forward, right, down   gravity positive  Freescale NED
enu         east, north, up        forward, left, up      specific force    ROS RPY (ZYX)
android     east, north, up        right, forward, up     specific force    Freescale Android
win8        east, north, up        right, forward, up     gravity positive  Freescale Win8
==========  =====================  =====================  ================  ===============

``aerospace``, ``android`` and ``win8`` are the three systems of the Freescale sensor fusion
note (Aerospace/NED is gravity positive there, unlike imuhal's ``ned``). ``enu`` is ROS
REP-103 (``ros`` and ``flu`` are aliases): sensor_msgs/Imu ``linear_acceleration`` is specific
force, ``orientation`` rotates the FLU body into ENU.

Quaternions are Hamilton, scalar first (w, x, y, z), rotating the convention's body axes into
its earth frame: ``v_earth = q v_body q*``.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from enum import Enum
from typing import NamedTuple

import numpy as np
from numpy.typing import ArrayLike

from imuhal.core.frames import FloatArray, quat_from_matrix, quat_to_matrix

_EARTH_DIRECTIONS: dict[str, tuple[float, float, float]] = {
    "north": (1.0, 0.0, 0.0), "south": (-1.0, 0.0, 0.0),
    "east": (0.0, 1.0, 0.0), "west": (0.0, -1.0, 0.0),
    "down": (0.0, 0.0, 1.0), "up": (0.0, 0.0, -1.0),
}
"""Each earth direction written in NED."""

_BODY_DIRECTIONS: dict[str, tuple[float, float, float]] = {
    "forward": (1.0, 0.0, 0.0), "back": (-1.0, 0.0, 0.0),
    "right": (0.0, 1.0, 0.0), "left": (0.0, -1.0, 0.0),
    "down": (0.0, 0.0, 1.0), "up": (0.0, 0.0, -1.0),
}
"""Each body direction written in FRD (x forward, y right, z down)."""


class AccelSign(str, Enum):
    """How an accelerometer reading relates to specific force f = a - g."""

    SPECIFIC_FORCE = "specific_force"
    """The reading is f ("acceleration positive"): level and still reads +1 g along up."""
    GRAVITY_POSITIVE = "gravity_positive"
    """The reading is -f: level and still reads +1 g along down."""

    @property
    def factor(self) -> float:
        """+1 or -1: reading = factor * specific force."""
        return 1.0 if self is AccelSign.SPECIFIC_FORCE else -1.0


class EulerStyle(str, Enum):
    """Which Euler angle definition a convention uses (see ``euler_deg_from_quat``)."""

    ZYX = "zyx"
    """R = Rz(yaw) Ry(pitch) Rx(roll) about the convention's own axes: aerospace for NED/FRD
    (yaw clockwise from north, pitch nose up, roll right wing down), ROS RPY for ENU/FLU
    (yaw anticlockwise from east, pitch nose *down* positive, roll right wing down as well).
    Roll and yaw in [-180, 180], pitch in [-90, 90]."""
    FREESCALE_NED = "freescale_ned"
    """The note's aerospace angles: ZYX as above with yaw (= compass heading) in [0, 360) and
    roll in [-180, 180)."""
    FREESCALE_ANDROID = "freescale_android"
    """The note's Android angles: body -> earth = Rz(-yaw) Ry(-roll) Rx(-pitch); roll about
    the forward (y) axis in [-90, 90], pitch about the right (x) axis in [-180, 180), yaw
    clockwise from north in [0, 360) (= compass heading)."""
    FREESCALE_WIN8 = "freescale_win8"
    """The note's Windows 8 angles: body -> earth = Rz(yaw) Rx(pitch) Ry(roll); roll in
    [-90, 90], pitch in [-180, 180), yaw anticlockwise from north in [0, 360) (the compass
    heading is 360 - yaw)."""


class EulerDeg(NamedTuple):
    """Euler angles in degrees, each with the meaning its convention gives it."""

    roll: float
    pitch: float
    yaw: float


@dataclass(frozen=True)
class Convention:
    """An earth frame, body axes, accelerometer sign and Euler definition (module docstring)."""

    name: str
    earth_axes: tuple[str, str, str]
    body_axes: tuple[str, str, str]
    accel_sign: AccelSign
    euler: EulerStyle
    description: str = ""
    earth_from_ned: FloatArray = field(init=False, repr=False, compare=False)
    """E with v_earth = E @ v_ned (a proper rotation)."""
    body_from_frd: FloatArray = field(init=False, repr=False, compare=False)
    """B with v_body = B @ v_frd (a proper rotation)."""

    def __post_init__(self) -> None:
        earth = _axes_matrix(self.name, "earth", self.earth_axes, _EARTH_DIRECTIONS)
        body = _axes_matrix(self.name, "body", self.body_axes, _BODY_DIRECTIONS)
        object.__setattr__(self, "earth_from_ned", earth)
        object.__setattr__(self, "body_from_frd", body)

    @property
    def level_accel_reading_g(self) -> FloatArray:
        """What a level accelerometer at rest reads in this convention (g, body axes)."""
        return vector_from_ned(np.array([0.0, 0.0, -1.0]), self, VectorKind.SPECIFIC_FORCE)


def _axes_matrix(name: str, what: str, axes: Sequence[str],
                 directions: dict[str, tuple[float, float, float]]) -> FloatArray:
    unknown = [a for a in axes if a not in directions]
    if len(axes) != 3 or unknown:
        raise ValueError(f"convention {name!r}: {what} axes must be three of "
                         f"{', '.join(directions)}; got {list(axes)}")
    m = np.array([directions[a] for a in axes])
    det = float(np.linalg.det(m))
    if round(det) != 1:
        raise ValueError(f"convention {name!r}: {what} axes {'-'.join(axes)} are not a "
                         "right-handed frame (they must be a proper rotation of "
                         f"{'NED' if what == 'earth' else 'FRD'}; determinant {det:+.0f})")
    return m


class VectorKind(str, Enum):
    """What a body-frame vector measures (only specific force has a sign convention)."""

    SPECIFIC_FORCE = "specific_force"
    """Accelerometer reading (any unit); carries the convention's accelerometer sign."""
    ANGULAR_RATE = "angular_rate"
    """Gyro reading, right-hand rule about the body axes."""
    MAGNETIC_FIELD = "magnetic_field"
    """Magnetometer reading."""


NED = Convention("ned", ("north", "east", "down"), ("forward", "right", "down"),
                 AccelSign.SPECIFIC_FORCE, EulerStyle.ZYX,
                 "imuhal's internal convention (aerospace axes, specific force)")
AEROSPACE = Convention("aerospace", ("north", "east", "down"), ("forward", "right", "down"),
                       AccelSign.GRAVITY_POSITIVE, EulerStyle.FREESCALE_NED,
                       "Freescale sensor fusion Aerospace/NED: gravity positive")
ENU = Convention("enu", ("east", "north", "up"), ("forward", "left", "up"),
                 AccelSign.SPECIFIC_FORCE, EulerStyle.ZYX,
                 "ROS REP-103: ENU earth, FLU body (sensor_msgs/Imu)")
ANDROID = Convention("android", ("east", "north", "up"), ("right", "forward", "up"),
                     AccelSign.SPECIFIC_FORCE, EulerStyle.FREESCALE_ANDROID,
                     "Freescale sensor fusion Android: acceleration positive")
WIN8 = Convention("win8", ("east", "north", "up"), ("right", "forward", "up"),
                  AccelSign.GRAVITY_POSITIVE, EulerStyle.FREESCALE_WIN8,
                  "Freescale sensor fusion Windows 8: gravity positive")

CONVENTIONS: dict[str, Convention] = {c.name: c for c in (NED, AEROSPACE, ENU, ANDROID, WIN8)}
"""The named conventions by name."""

ALIASES: dict[str, str] = {"ros": "enu", "flu": "enu", "frd": "ned"}


class UnknownConvention(ValueError):
    """A convention name that is not one of ``CONVENTIONS`` (or an alias)."""


def get_convention(name: str | Convention) -> Convention:
    """The convention called ``name`` (case-insensitive; ``ros``/``flu`` mean ``enu``)."""
    if isinstance(name, Convention):
        return name
    key = str(name).strip().lower()
    key = ALIASES.get(key, key)
    try:
        return CONVENTIONS[key]
    except KeyError:
        raise UnknownConvention(
            f"unknown frame convention {name!r}; choose one of "
            f"{', '.join(CONVENTIONS)} (aliases: "
            f"{', '.join(f'{a}={t}' for a, t in ALIASES.items())})") from None


def convention_name(value: str) -> str:
    """The canonical name of the convention called ``value``; as a pydantic field validator,
    an unknown name is a plain ValueError naming the choices."""
    try:
        return get_convention(value).name
    except UnknownConvention as exc:
        raise ValueError(str(exc)) from None


# ---------------------------------------------------------------------------------------------
# vectors


def _vectors(v: ArrayLike) -> FloatArray:
    a = np.asarray(v, dtype=float)
    if a.shape[-1:] != (3,):
        raise ValueError(f"vectors must have 3 components in the last axis, got shape {a.shape}")
    return a


def vector_to_ned(v: ArrayLike, src: str | Convention, kind: VectorKind) -> FloatArray:
    """A body-frame reading in ``src`` as imuhal's FRD body axes (specific force for the
    accelerometer). ``v`` may be one vector or an (..., 3) array; units are unchanged."""
    c = get_convention(src)
    a = _vectors(v) @ c.body_from_frd  # row vectors: (B^T v^T)^T
    return a * c.accel_sign.factor if kind is VectorKind.SPECIFIC_FORCE else a


def vector_from_ned(v: ArrayLike, dst: str | Convention, kind: VectorKind) -> FloatArray:
    """An FRD body-frame reading (specific force for the accelerometer) in ``dst``'s body
    axes and accelerometer sign."""
    c = get_convention(dst)
    a: FloatArray = _vectors(v) @ c.body_from_frd.T
    return a * c.accel_sign.factor if kind is VectorKind.SPECIFIC_FORCE else a


def convert_vector(v: ArrayLike, src: str | Convention, dst: str | Convention,
                   kind: VectorKind) -> FloatArray:
    """A body-frame reading from ``src`` to ``dst`` (axes and, for specific force, sign)."""
    return vector_from_ned(vector_to_ned(v, src, kind), dst, kind)


def convert_earth_vector(v: ArrayLike, src: str | Convention,
                         dst: str | Convention) -> FloatArray:
    """An earth-frame vector (position, velocity, linear acceleration, a field reference)
    from ``src``'s earth axes to ``dst``'s."""
    s, d = get_convention(src), get_convention(dst)
    out: FloatArray = _vectors(v) @ (d.earth_from_ned @ s.earth_from_ned.T).T
    return out


# ---------------------------------------------------------------------------------------------
# quaternions


def _quats(q: ArrayLike) -> FloatArray:
    a = np.asarray(q, dtype=float)
    if a.shape[-1:] != (4,):
        raise ValueError(f"quaternions must have 4 components (w, x, y, z), got shape {a.shape}")
    return a


def _quat_mul_rows(p: FloatArray, q: FloatArray) -> FloatArray:
    pw, px, py, pz = np.moveaxis(p, -1, 0)
    qw, qx, qy, qz = np.moveaxis(q, -1, 0)
    return np.stack([
        pw * qw - px * qx - py * qy - pz * qz,
        pw * qx + px * qw + py * qz - pz * qy,
        pw * qy - px * qz + py * qw + pz * qx,
        pw * qz + px * qy - py * qx + pz * qw,
    ], axis=-1)


def convert_quat(q: ArrayLike, src: str | Convention, dst: str | Convention) -> FloatArray:
    """A body -> earth quaternion of ``src`` as the body -> earth quaternion of ``dst``: both
    endpoints re-expressed (R_dst = E_dst E_src^T R_src B_src B_dst^T).

    Computed as e * q * b* with e, b the unit quaternions of the earth and body axis changes,
    so it is continuous along a trajectory and keeps the input's sign choice (no flips to
    w >= 0 that a plotted component would show as jumps). ``q`` may be (..., 4).
    """
    s, d = get_convention(src), get_convention(dst)
    a = _quats(q)
    e = quat_from_matrix(d.earth_from_ned @ s.earth_from_ned.T)
    b = quat_from_matrix(d.body_from_frd @ s.body_from_frd.T)
    b_conj = b * np.array([1.0, -1.0, -1.0, -1.0])
    return _quat_mul_rows(_quat_mul_rows(np.broadcast_to(e, a.shape), a),
                          np.broadcast_to(b_conj, a.shape))


# ---------------------------------------------------------------------------------------------
# Euler angles


def _rx(a: float) -> FloatArray:
    c, s = math.cos(a), math.sin(a)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def _ry(a: float) -> FloatArray:
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def _rz(a: float) -> FloatArray:
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def _asin_deg(x: float) -> float:
    return math.degrees(math.asin(max(-1.0, min(1.0, x))))


def _atan2_deg(y: float, x: float) -> float:
    return math.degrees(math.atan2(y, x))


def _wrap_360(a: float) -> float:
    a = a + 360.0 if a < 0.0 else a
    return 0.0 if a >= 360.0 else a


def quat_from_euler_deg(conv: str | Convention, roll_deg: float, pitch_deg: float,
                        yaw_deg: float) -> FloatArray:
    """Body -> earth quaternion (w >= 0) of ``conv`` from its own Euler angles (degrees)."""
    c = get_convention(conv)
    r, p, y = (math.radians(v) for v in (roll_deg, pitch_deg, yaw_deg))
    if c.euler in (EulerStyle.ZYX, EulerStyle.FREESCALE_NED):
        m = _rz(y) @ _ry(p) @ _rx(r)
    elif c.euler is EulerStyle.FREESCALE_ANDROID:
        m = _rz(-y) @ _ry(-r) @ _rx(-p)
    else:
        m = _rz(y) @ _rx(p) @ _ry(r)
    return quat_from_matrix(m)


def euler_deg_from_quat(conv: str | Convention, q: ArrayLike) -> EulerDeg:
    """``conv``'s Euler angles (degrees) of its body -> earth quaternion ``q``.

    The Freescale styles follow the note's extraction (orientation.c of the reference library)
    from R = C(q)^T (earth -> body), gimbal-lock branches included.
    """
    c = get_convention(conv)
    a = _quats(q)
    n = float(np.linalg.norm(a))
    if not n > 0.0 or not math.isfinite(n):
        raise ValueError(f"cannot take Euler angles of quaternion {a.tolist()}")
    m = quat_to_matrix(a / n)
    if c.euler is EulerStyle.ZYX:
        roll = _atan2_deg(m[2, 1], m[2, 2])
        pitch = _asin_deg(-m[2, 0])
        yaw = _atan2_deg(m[1, 0], m[0, 0])
        return EulerDeg(roll, pitch, yaw)
    r = m.T  # the note's R: earth -> body
    if c.euler is EulerStyle.FREESCALE_NED:
        return _freescale_ned(r)
    if c.euler is EulerStyle.FREESCALE_ANDROID:
        return _freescale_android(r)
    return _freescale_win8(r)


def _freescale_ned(r: FloatArray) -> EulerDeg:
    theta = _asin_deg(-r[0, 2])
    phi = _atan2_deg(r[1, 2], r[2, 2])
    phi = -180.0 if phi == 180.0 else phi
    if theta == 90.0:
        psi = _atan2_deg(r[2, 1], r[1, 1]) + phi
    elif theta == -90.0:
        psi = _atan2_deg(-r[2, 1], r[1, 1]) - phi
    else:
        psi = _atan2_deg(r[0, 1], r[0, 0])
    return EulerDeg(phi, theta, _wrap_360(psi))


def _freescale_android(r: FloatArray) -> EulerDeg:
    phi = _asin_deg(r[0, 2])
    theta = _atan2_deg(-r[1, 2], r[2, 2])
    theta = -180.0 if theta == 180.0 else theta
    if phi == 90.0:
        psi = _atan2_deg(r[1, 0], r[1, 1]) - theta
    elif phi == -90.0:
        psi = _atan2_deg(r[1, 0], r[1, 1]) + theta
    else:
        psi = _atan2_deg(-r[0, 1], r[0, 0])
    return EulerDeg(phi, theta, _wrap_360(psi))


def _freescale_win8(r: FloatArray) -> EulerDeg:
    if r[2, 2] == 0.0:
        phi = -90.0 if r[0, 2] >= 0.0 else 90.0
    else:
        phi = math.degrees(math.atan(-r[0, 2] / r[2, 2]))
    theta = _asin_deg(r[1, 2])
    if r[2, 2] < 0.0:  # cos(phi) >= 0, so cos(theta) has the sign of R[2][2]
        theta = 180.0 - theta
    if theta >= 180.0:
        theta -= 360.0
    if theta == 90.0:
        psi = _atan2_deg(r[0, 1], r[0, 0]) - phi
    elif theta == -90.0:
        psi = _atan2_deg(r[0, 1], r[0, 0]) + phi
    else:
        psi = _atan2_deg(-r[1, 0], r[1, 1])
        if abs(theta) >= 90.0:
            psi += 180.0
    return EulerDeg(phi, theta, _wrap_360(psi))


def compass_heading_deg(conv: str | Convention, q: ArrayLike) -> float:
    """Heading clockwise from north, [0, 360), of the body's forward axis (any convention).
    Undefined (whatever atan2 gives) when the forward axis is vertical."""
    q_ned = convert_quat(q, conv, NED)
    fwd = quat_to_matrix(q_ned / np.linalg.norm(q_ned))[:, 0]
    return _wrap_360(_atan2_deg(fwd[1], fwd[0]))


def convert_euler_deg(angles: Sequence[float], src: str | Convention,
                      dst: str | Convention) -> EulerDeg:
    """``src``'s Euler angles (roll, pitch, yaw; degrees) as ``dst``'s Euler angles."""
    roll, pitch, yaw = angles
    q = quat_from_euler_deg(src, roll, pitch, yaw)
    return euler_deg_from_quat(dst, convert_quat(q, src, dst))


__all__ = [
    "AEROSPACE", "ALIASES", "ANDROID", "CONVENTIONS", "ENU", "NED", "WIN8",
    "AccelSign", "Convention", "EulerDeg", "EulerStyle", "UnknownConvention", "VectorKind",
    "compass_heading_deg", "convert_earth_vector", "convert_euler_deg", "convert_quat",
    "convert_vector", "euler_deg_from_quat", "get_convention", "quat_from_euler_deg",
    "vector_from_ned", "vector_to_ned",
]
