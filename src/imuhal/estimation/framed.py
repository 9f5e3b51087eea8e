"""Samples and estimates expressed in another coordinate convention, for the edges.

Inside imuhal everything is ``ned`` (earth north-east-down, body forward-right-down,
specific force; imuhal.core.conventions). Sinks, embedding programs and offline outputs may
want another convention (ROS ``enu``, ``android`` ...): ``express(event, frame)`` gives a
read-only view of one event in that convention, and ``sample_from_frame`` builds the NED
sample the pipeline needs from a reading given in another convention. Estimators never see
anything but NED.

Column names used by the CSV writers: a frame-dependent column carries the convention's name
as a suffix (``qw_enu``, ``ax_m_s2_android``) except in ``ned``, whose names are unsuffixed;
earth-frame vectors name the convention's earth axes (``lin_ae_m_s2``, ``lin_an_m_s2``,
``lin_au_m_s2`` in ENU). So a header always says which frame its columns are in.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from imuhal.core.conventions import (
    NED,
    Convention,
    EulerDeg,
    VectorKind,
    convert_earth_vector,
    convert_quat,
    euler_deg_from_quat,
    get_convention,
    vector_from_ned,
    vector_to_ned,
)
from imuhal.core.samples import (
    AccelSample,
    Frame,
    GyroSample,
    MagSample,
    Quantity,
    Sample,
    SampleFlag,
    Vec3,
    VectorSample,
)
from imuhal.estimation.outputs import AttitudeEstimate, Estimate

_KIND = {Quantity.ACCEL: VectorKind.SPECIFIC_FORCE, Quantity.GYRO: VectorKind.ANGULAR_RATE,
         Quantity.MAG: VectorKind.MAGNETIC_FIELD}

VECTOR_COLUMNS = {
    Quantity.ACCEL: ("ax_m_s2", "ay_m_s2", "az_m_s2"),
    Quantity.GYRO: ("gx_rad_s", "gy_rad_s", "gz_rad_s"),
    Quantity.MAG: ("mx_ut", "my_ut", "mz_ut"),
}
"""Body-frame sample columns in ``ned`` (other conventions add their suffix)."""

QUAT_COLUMNS = ("qw", "qx", "qy", "qz")
EULER_COLUMNS = ("roll_deg", "pitch_deg", "yaw_deg")
_AXIS_LETTER = {"north": "n", "south": "s", "east": "e", "west": "w", "up": "u", "down": "d"}


def frame_suffix(frame: str | Convention) -> str:
    """``""`` for ned, ``"_<name>"`` otherwise: appended to frame-dependent column names."""
    c = get_convention(frame)
    return "" if c is NED else f"_{c.name}"


def vector_columns(channel: Quantity, frame: str | Convention) -> tuple[str, str, str]:
    """Column names of a body-frame sample vector in ``frame``."""
    sfx = frame_suffix(frame)
    x, y, z = VECTOR_COLUMNS[channel]
    return (x + sfx, y + sfx, z + sfx)


def attitude_columns(frame: str | Convention) -> tuple[str, ...]:
    """Quaternion (body -> earth of ``frame``) and Euler angle columns (``frame``'s own)."""
    sfx = frame_suffix(frame)
    return tuple(c + sfx for c in (*QUAT_COLUMNS, *EULER_COLUMNS))


def linear_accel_columns(frame: str | Convention) -> tuple[str, str, str]:
    """Earth-frame linear acceleration columns, named for the earth axes of ``frame``."""
    a, b, c = (f"lin_a{_AXIS_LETTER[axis]}_m_s2" for axis in get_convention(frame).earth_axes)
    return (a, b, c)


@dataclass(frozen=True, slots=True)
class FramedSample:
    """A body-frame vector sample in ``frame``: its axes, and for the accelerometer its sign
    (a gravity-positive convention reads minus the specific force)."""

    sample: VectorSample
    """The NED sample it came from."""
    frame: Convention
    vector: Vec3
    """The reading in the unit of ``sample.channel``, axes and sign of ``frame``."""

    @property
    def t_ns(self) -> int:
        return self.sample.t_ns

    @property
    def channel(self) -> Quantity:
        return self.sample.channel

    @property
    def valid(self) -> bool:
        return self.sample.valid

    def columns(self) -> dict[str, float]:
        return dict(zip(vector_columns(self.channel, self.frame), self.vector, strict=True))


@dataclass(frozen=True, slots=True)
class FramedAttitude:
    """An attitude estimate in ``frame``: quaternion body -> earth of that convention, its
    own Euler angles, linear acceleration in its earth axes."""

    estimate: AttitudeEstimate
    """The NED estimate it came from."""
    frame: Convention
    q_body_to_earth: tuple[float, float, float, float]
    euler_deg: EulerDeg
    linear_accel_earth_m_s2: Vec3 | None = None
    diagnostics: dict[str, Any] = field(default_factory=dict)
    """The estimator's diagnostics, unconverted (its own internal NED body frame)."""

    @property
    def t_ns(self) -> int:
        return self.estimate.t_ns

    @property
    def source(self) -> str:
        return self.estimate.source

    def columns(self) -> dict[str, float]:
        out = dict(zip(attitude_columns(self.frame), (*self.q_body_to_earth, *self.euler_deg),
                       strict=True))
        if self.linear_accel_earth_m_s2 is not None:
            out.update(zip(linear_accel_columns(self.frame), self.linear_accel_earth_m_s2,
                           strict=True))
        return out


FramedEvent = FramedSample | FramedAttitude | Sample | Estimate
"""What ``express`` returns: a framed view, or the event itself when it has no frame
(pressure, temperature, vertical estimates, sensor-frame samples)."""


def _vec3(a: np.ndarray) -> Vec3:
    return (float(a[0]), float(a[1]), float(a[2]))


def express_attitude(est: AttitudeEstimate, frame: str | Convention) -> FramedAttitude:
    """``est`` (body -> NED) in ``frame``."""
    c = get_convention(frame)
    if c is NED:  # the common case, on every estimate of a run: no arithmetic
        return FramedAttitude(estimate=est, frame=c, q_body_to_earth=est.q_body_to_ned,
                              euler_deg=EulerDeg(*est.roll_pitch_yaw_deg),
                              linear_accel_earth_m_s2=est.linear_accel_ned_m_s2,
                              diagnostics=est.diagnostics)
    q = convert_quat(est.q_body_to_ned, NED, c)
    lin = None
    if est.linear_accel_ned_m_s2 is not None:
        lin = _vec3(convert_earth_vector(est.linear_accel_ned_m_s2, NED, c))
    return FramedAttitude(
        estimate=est, frame=c,
        q_body_to_earth=(float(q[0]), float(q[1]), float(q[2]), float(q[3])),
        euler_deg=euler_deg_from_quat(c, q), linear_accel_earth_m_s2=lin,
        diagnostics=est.diagnostics)


def express_sample(sample: VectorSample, frame: str | Convention) -> FramedSample:
    """A body-NED vector sample in ``frame``."""
    if sample.frame is not Frame.BODY_NED:
        raise ValueError(f"a {sample.frame.value}-frame sample has no body axes to re-express; "
                         "only body-frame samples convert between conventions")
    c = get_convention(frame)
    if c is NED:
        return FramedSample(sample=sample, frame=c, vector=sample.vector)
    v = vector_from_ned(sample.vector, c, _KIND[sample.channel])
    return FramedSample(sample=sample, frame=c, vector=_vec3(v))


def express(event: Sample | Estimate, frame: str | Convention) -> FramedEvent:
    """``event`` in ``frame``; events without a frame come back unchanged."""
    if isinstance(event, AttitudeEstimate):
        return express_attitude(event, frame)
    if isinstance(event, VectorSample) and event.frame is Frame.BODY_NED:
        return express_sample(event, frame)
    return event


def sample_from_frame(channel: Quantity, vector: Vec3 | np.ndarray, frame: str | Convention, *,
                      t_ns: int, device: str,
                      flags: SampleFlag = SampleFlag.OK) -> VectorSample:
    """The body-NED sample (specific force for the accelerometer) of a reading given in the
    body axes and sign of ``frame``: what a program feeding imuhal from ROS, a phone or a
    dataset calls at its input edge."""
    v = _vec3(vector_to_ned(vector, frame, _KIND[channel]))
    if channel is Quantity.ACCEL:
        return AccelSample(t_ns=t_ns, device=device, frame=Frame.BODY_NED, flags=flags,
                           accel_m_s2=v)
    if channel is Quantity.GYRO:
        return GyroSample(t_ns=t_ns, device=device, frame=Frame.BODY_NED, flags=flags,
                          gyro_rad_s=v)
    if channel is Quantity.MAG:
        return MagSample(t_ns=t_ns, device=device, frame=Frame.BODY_NED, flags=flags, mag_ut=v)
    raise ValueError(f"{channel.value} samples have no axes; build them directly")
