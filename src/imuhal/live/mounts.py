"""Board bring-up: do the profile's mounts turn the chips' axes the right way?

The user (or the ``bringup`` scenario) performs three motions; each sensor's body-frame
samples must show that motion about the right body axis, with the right sign (NED body
frame, right-handed rotations):

- **tilt nose up**: positive rotation about body y (gyro y > 0);
- **roll right** (right side down): positive rotation about body x (gyro x > 0);
- **turn right** (clockwise seen from above): positive rotation about body z (gyro z > 0).

A gyro shows the rotation directly (its rate integrated over the motion). An accelerometer
or magnetometer shows it as the turn of a fixed earth vector (gravity, the earth's field)
seen from the body, which turns the opposite way: the body rotated by ``-(v0 x v1)``. Such a
sensor cannot see a rotation about its own vector (an accelerometer cannot see a level turn),
so it is judged only on the part of the motion it can see.

Pure functions and a recorder sink: used by the live page (imuhal.live.snapshot) and by
``imuhal check-mounts`` (imuhal.cli.check_mounts_cmd).
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from imuhal.core.samples import Quantity, Vec3, VectorSample
from imuhal.sinks.base import Event

MIN_MOTION_DEG = 10.0
"""A rotation smaller than this (deg) is not a motion: the user is asked to move more."""
MIN_OBSERVABLE = 0.3
"""A vector sensor sees a motion when the part of its axis perpendicular to the sensor's
earth vector is at least this long (unit axis); below, the motion is invisible to it."""
MIN_AGREEMENT = 0.8
"""Cosine between the seen and the expected rotation for a pass (about 37 deg apart)."""
ENDS_S = 0.25
"""An accelerometer or magnetometer vector is averaged over this long at each end of the
motion (s), against noise."""

CHECKED_CHANNELS = (Quantity.GYRO, Quantity.ACCEL, Quantity.MAG)


@dataclass(frozen=True)
class Motion:
    """One bring-up motion: a positive rotation about body ``axis`` (0 x, 1 y, 2 z; NED)."""

    key: str
    label: str
    prompt: str
    axis: int


MOTIONS: tuple[Motion, ...] = (
    Motion("nose-up", "tilt nose up",
           "tilt the nose up about 30 degrees and hold it there", 1),
    Motion("roll-right", "roll right",
           "roll right (right side down) about 30 degrees and hold it there", 0),
    Motion("turn-right", "turn right",
           "turn right (clockwise seen from above) about 90 degrees, level, and hold", 2),
)
MOTION_BY_KEY = {m.key: m for m in MOTIONS}

_AXIS_NAMES = {(0, 1): "roll right", (0, -1): "roll left", (1, 1): "nose up",
               (1, -1): "nose down", (2, 1): "turn right", (2, -1): "turn left"}


def motion_name(rotation_deg: Sequence[float]) -> str | None:
    """What a body rotation (deg, body axes) looks like to a user: ``"nose up"``, ... ;
    ``None`` below :data:`MIN_MOTION_DEG`."""
    size = _norm(rotation_deg)
    if size < MIN_MOTION_DEG:
        return None
    axis = max(range(3), key=lambda i: abs(rotation_deg[i]))
    name = _AXIS_NAMES[(axis, 1 if rotation_deg[axis] > 0 else -1)]
    share = abs(rotation_deg[axis]) / size
    return name if share >= MIN_AGREEMENT else f"mostly {name}"


@dataclass(frozen=True)
class Evidence:
    """The body rotation (deg, body axes) one sensor saw during a motion.

    ``reference`` is the unit earth vector a vector sensor measures it by (body axes, at the
    start), None for a gyro (which sees every axis)."""

    device: str
    channel: Quantity
    rotation_deg: Vec3
    reference: Vec3 | None = None


@dataclass(frozen=True)
class Verdict:
    """Whether one sensor saw ``motion`` the right way: ``ok`` is None when it could not tell
    (no clear motion, or a motion it cannot see)."""

    device: str
    channel: Quantity
    motion: str
    ok: bool | None
    seen: str
    message: str
    angle_deg: float = 0.0
    """How far the sensor saw the body turn (deg), whatever the direction."""
    rotation_deg: Vec3 = (0.0, 0.0, 0.0)
    """The body rotation it saw (deg, body axes)."""

    def as_dict(self) -> dict[str, object]:
        return {"device": self.device, "channel": self.channel.value, "motion": self.motion,
                "ok": self.ok, "seen": self.seen, "message": self.message,
                "angle_deg": self.angle_deg}


def rotation_between(v0: Sequence[float], v1: Sequence[float]) -> Vec3:
    """The body rotation (deg) that turns a fixed earth vector seen as ``v0`` into ``v1``:
    the vector turns the opposite way, ``-(v0 x v1)``, by the angle between them."""
    a, b = _unit(v0), _unit(v1)
    if a is None or b is None:
        return (0.0, 0.0, 0.0)
    c = _cross(a, b)
    s = _norm(c)
    if s == 0.0:
        return (0.0, 0.0, 0.0)
    angle = math.degrees(math.atan2(s, _dot(a, b)))
    return (-c[0] / s * angle, -c[1] / s * angle, -c[2] / s * angle)


def judge(motion: Motion, evidence: Evidence) -> Verdict:
    """Did ``evidence`` show ``motion`` about the right body axis with the right sign?"""
    rot = evidence.rotation_deg
    size = _norm(rot)
    seen = motion_name(rot) or "no motion"
    if size >= MIN_MOTION_DEG:
        seen = f"{seen} {size:.0f} deg"
    expected = [0.0, 0.0, 0.0]
    expected[motion.axis] = 1.0
    if evidence.reference is not None:
        ref = evidence.reference
        along = _dot(expected, ref)
        expected = [expected[i] - along * ref[i] for i in range(3)]
    visible = _norm(expected)
    what = f"{evidence.device} {evidence.channel.value}"

    def verdict(ok: bool | None, message: str) -> Verdict:
        return Verdict(evidence.device, evidence.channel, motion.key, ok, seen, message, size,
                       tuple(rot))  # type: ignore[arg-type]

    if visible < MIN_OBSERVABLE:
        # No verdict either way: what such a sensor shows about this motion is mostly the
        # error of its reference (an uncalibrated magnetometer's hard iron turns the vector
        # it measures); the motions it can see judge its mount.
        extra = "" if size < MIN_MOTION_DEG else f" (it showed {seen}, within its errors)"
        return verdict(None, f"{what}: cannot see '{motion.label}' (it turns about the "
                             f"{_vector_name(evidence.channel)} direction){extra}")
    if size < MIN_MOTION_DEG * visible:
        return verdict(None, f"{what}: no clear motion seen; {motion.prompt}")
    agreement = _dot(rot, expected) / (size * visible)
    if agreement >= MIN_AGREEMENT:
        return verdict(True, f"{what}: saw {seen}: right")
    return verdict(False, f"{what}: saw {seen} during '{motion.label}' (expected a positive "
                          f"rotation about body {'xyz'[motion.axis]}): check the mount of "
                          f"'{evidence.device}'")


class MotionRecorder:
    """A sink that records what each sensor saw between ``start()`` and ``evidence()``.

    Gyro rates (body frame, rad/s) are integrated sample by sample; accelerometer and
    magnetometer vectors are averaged over the first and the last :data:`ENDS_S` seconds.
    Flagged samples are skipped (never trusted). Events outside a recording are ignored.
    """

    def __init__(self) -> None:
        self.recording = False
        self._gyro: dict[str, list[float]] = {}
        self._gyro_t: dict[str, int] = {}
        self._first: dict[tuple[str, Quantity], list[VectorSample]] = {}
        self._last: dict[tuple[str, Quantity], deque[VectorSample]] = {}

    def start(self) -> None:
        self.recording = True
        self._gyro.clear()
        self._gyro_t.clear()
        self._first.clear()
        self._last.clear()

    def handle(self, event: Event) -> None:
        if not self.recording or not isinstance(event, VectorSample) or not event.valid:
            return
        channel = event.channel
        if channel is Quantity.GYRO:
            last = self._gyro_t.get(event.device)
            total = self._gyro.setdefault(event.device, [0.0, 0.0, 0.0])
            if last is not None and event.t_ns > last:
                dt = (event.t_ns - last) / 1e9
                w = event.vector
                for i in range(3):
                    total[i] += w[i] * dt
            self._gyro_t[event.device] = event.t_ns
        elif channel in (Quantity.ACCEL, Quantity.MAG):
            key = (event.device, channel)
            first = self._first.setdefault(key, [])
            if not first or event.t_ns - first[0].t_ns <= ENDS_S * 1e9:
                first.append(event)
            last_q = self._last.setdefault(key, deque())
            last_q.append(event)
            while event.t_ns - last_q[0].t_ns > ENDS_S * 1e9:
                last_q.popleft()

    def evidence(self) -> list[Evidence]:
        """What each sensor saw since ``start()`` (recording stops)."""
        self.recording = False
        out = [Evidence(dev, Quantity.GYRO, (math.degrees(r[0]), math.degrees(r[1]),
                                            math.degrees(r[2])))
               for dev, r in self._gyro.items()]
        for key, first in self._first.items():
            v0 = mean_vector([s.vector for s in first])
            v1 = mean_vector([s.vector for s in self._last[key]])
            out.append(Evidence(key[0], key[1], rotation_between(v0, v1), _unit(v0)))
        return out

    def close(self) -> None:
        self.recording = False


def check(motion: Motion, evidence: Sequence[Evidence]) -> list[Verdict]:
    """Every sensor's verdict on one motion, gyros first."""
    order = {c: i for i, c in enumerate(CHECKED_CHANNELS)}
    ranked = sorted(evidence, key=lambda e: (order.get(e.channel, 9), e.device))
    return [judge(motion, e) for e in ranked]


def mean_vector(vectors: Sequence[Sequence[float]]) -> Vec3:
    n = len(vectors)
    if n == 0:
        return (0.0, 0.0, 0.0)
    return (sum(v[0] for v in vectors) / n, sum(v[1] for v in vectors) / n,
            sum(v[2] for v in vectors) / n)


def _vector_name(channel: Quantity) -> str:
    return "gravity" if channel is Quantity.ACCEL else "magnetic field"


def _dot(a: Sequence[float], b: Sequence[float]) -> float:
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


def _cross(a: Sequence[float], b: Sequence[float]) -> Vec3:
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


def _norm(v: Sequence[float]) -> float:
    return math.sqrt(_dot(v, v))


def _unit(v: Sequence[float]) -> Vec3 | None:
    n = _norm(v)
    if n == 0.0 or not math.isfinite(n):
        return None
    return (v[0] / n, v[1] / n, v[2] / n)


def suggest_mount(chip_to_body: Sequence[Sequence[float]],
                  board_to_body: Sequence[Sequence[float]],
                  seen_deg: dict[str, Sequence[float]]) -> str | None:
    """The mount (chip -> board, signed axes) that explains what a gyro saw, or None.

    ``seen_deg`` holds the body rotation (deg) the gyro showed for each motion of
    :data:`MOTIONS`, through the profile's ``chip_to_body`` rotation C. If the chip really
    sits at C', the gyro shows M e for a true rotation e, with M = C C'^T; the three motions
    give M column by column (rounded to the nearest signed axis), so C' = M^T C and the mount
    is ``board_to_body^T C'``. None unless every motion was clear and the result is a proper
    signed-axis rotation.
    """
    m = np.zeros((3, 3))
    for motion in MOTIONS:
        rot = seen_deg.get(motion.key)
        if rot is None or _norm(rot) < MIN_MOTION_DEG:
            return None
        axis = max(range(3), key=lambda i: abs(rot[i]))
        if abs(rot[axis]) < MIN_AGREEMENT * _norm(rot):
            return None
        m[axis, motion.axis] = 1.0 if rot[axis] > 0 else -1.0
    if abs(np.linalg.det(m) - 1.0) > 1e-9:
        return None
    mount = np.asarray(board_to_body, dtype=float).T @ m.T @ np.asarray(chip_to_body,
                                                                         dtype=float)
    terms = []
    for row in np.rint(mount):
        (j,) = np.flatnonzero(row)
        terms.append(("+" if row[j] > 0 else "-") + "XYZ"[j])
    return "".join(terms)
