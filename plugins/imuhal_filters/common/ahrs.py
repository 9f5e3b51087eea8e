"""Base class of the AHRS estimators: turns a stream of samples into one filter step per gyro.

What every AHRS plugin shares lives here so the filters themselves are only their kernels:

- gyro, accelerometer and magnetometer samples arrive separately; the estimator keeps the
  latest valid accel and mag and runs one step per valid gyro sample with them (an accel or mag
  older than ``max_aux_age_s`` is not used);
- invalid samples (``sample.valid`` False) are never fused: they are counted per channel;
- the step length comes from consecutive gyro timestamps (or the nominal ``sample_period_s``
  for the first step, for gaps longer than ``max_dt_s`` and for non-increasing timestamps),
  except that a step over frames the pipeline counted lost (a ``StreamGap`` before it,
  imuhal.core.gaps) is integrated over its true interval up to ``max_gap_s``;
- accelerometer values are handed to the kernel gravity positive in g (the unit of the
  reference code), magnetometer values in uT, gyro in rad/s, all in body NED axes;
- each step emits an :class:`AttitudeEstimate` with the body -> NED quaternion and, when an
  accel sample is at hand, the gravity-compensated acceleration in NED (m/s^2);
- gyro and accelerometer values beyond the configured physical full scale, NaN or infinite
  are never fused: they are counted (``beyond_full_scale``) and dropped (``limits``);
- with ``initial_attitude: first_sample`` (the default) the first accelerometer sample (and
  the first magnetometer sample, for a filter that uses one) sets the attitude (``alignment``)
  and nothing is emitted before it; ``identity`` is the references' start;
- the kinematic acceleration from a velocity, airspeed or nominal airspeed source is removed
  from the specific force before the kernel sees it (``turn``);
- for a filter whose settings have rest detection (``rest``: madgwick, mahony), the rest
  detector runs before each step (on the turn-compensated accelerometer): the step gets the
  gyro less the bias learned at rest and the verdict (``_at_rest``: no soft gate);
- the state (quaternion, held samples, counters, filter internals) can be saved and restored.

Subclasses implement ``_reset_filter``, ``_step``, ``_filter_state`` and ``_set_filter_state``
and expose their quaternion through ``_q``.
"""

from __future__ import annotations

import math
import sys
from abc import abstractmethod
from collections.abc import Sequence
from functools import partial
from typing import Any, ClassVar, Literal, NamedTuple, cast

import numpy as np
from pydantic import Field

from imuhal.core.atmosphere import STANDARD_GRAVITY_M_S2
from imuhal.core.blocks import Block
from imuhal.core.frames import FloatArray
from imuhal.core.gaps import StreamGap
from imuhal.core.quantities import Quantity
from imuhal.core.samples import (
    AccelSample,
    AirspeedSample,
    Frame,
    GyroSample,
    MagSample,
    Sample,
    SampleFlag,
    VelocitySample,
)
from imuhal.core.streams import StreamSpec
from imuhal.estimation.base import Estimator, EstimatorSettings
from imuhal.estimation.outputs import (
    AttitudeBlock,
    AttitudeEstimate,
    Estimate,
    EstimateFlag,
    RejectedEstimate,
)
from imuhal.estimation.rows import (
    AttitudeRows,
    DiagnosticColumn,
    flatten_diagnostics,
    merge_columns,
)
from imuhal.estimation.streams import stream_of
from imuhal_filters.common import fast
from imuhal_filters.common.alignment import aligned_quaternion
from imuhal_filters.common.fast_ahrs import rest_update
from imuhal_filters.common.gate import gravity_positive_g
from imuhal_filters.common.limits import (
    DEFAULT_ACCEL_FULL_SCALE_M_S2,
    DEFAULT_GYRO_FULL_SCALE_RAD_S,
    bound_settings,
    within_full_scale,
)
from imuhal_filters.common.presets import PresetSettings
from imuhal_filters.common.quat import IDENTITY, Quat, Vec, to_local
from imuhal_filters.common.rest import REST_OFF, REST_START, RestSettings, rest_params
from imuhal_filters.common.rows import StepRows, block_rows
from imuhal_filters.common.turn import (
    KinematicAcceleration,
    TurnCompensationSettings,
    compensated,
    nominal_rows,
)

_NS = 1e-9


class AhrsLimitSettings(EstimatorSettings):
    """The physical full scales beyond which a value is never fused (``limits``)."""

    gyro_full_scale_rad_s: float = Field(DEFAULT_GYRO_FULL_SCALE_RAD_S, gt=0.0)
    """A gyro component beyond +-this (rad/s) is impossible: the sample is dropped, counted."""
    accel_full_scale_m_s2: float = Field(DEFAULT_ACCEL_FULL_SCALE_M_S2, gt=0.0)
    """An accelerometer component beyond +-this (m/s^2) is dropped and counted."""


class AhrsSettings(PresetSettings, AhrsLimitSettings, TurnCompensationSettings):
    """Settings every AHRS shares. Times in seconds."""

    initial_attitude: Literal["first_sample", "identity"] = "first_sample"
    """``first_sample``: the first accel (and mag) sample sets the attitude (tilt from
    gravity, heading from the tilt-compensated field); ``identity``: start level, facing
    north, as the reference implementations do (``preset: reference``)."""

    sample_period_s: float = Field(0.005, gt=0.0)
    """Nominal gyro period: the first step, and any step whose timestamps cannot be used."""
    dt_from_timestamps: bool = True
    """Step length from consecutive gyro timestamps (False: always ``sample_period_s``)."""
    max_dt_s: float = Field(0.1, gt=0.0)
    """A gyro gap longer than this is not integrated over: the nominal period is used instead
    (a step nobody explained may be a time stamp that jumped), unless the pipeline counted
    it as lost frames (``max_gap_s``)."""
    max_gap_s: float = Field(1.0, gt=0.0)
    """A gyro step over frames the pipeline counted lost (a StreamGap before it: a stall, a
    bus error, a reset, imuhal.core.gaps) is real time: up to this long it is integrated
    over its true interval with the rate after it; longer, over the nominal period (the
    rotation in a long loss is unknown; the accelerometer and magnetometer take the attitude
    back)."""
    max_aux_age_s: float | None = Field(0.1, gt=0.0)
    """An accel or mag sample older than this (relative to the gyro sample) is not used."""
    start_check_s: float | None = Field(1.0, gt=0.0)
    """After a start in motion (the pipeline's gyro start-up measurement gave up, the board
    moved: ``Estimator.moving_at_start``), the attitude aligned from the sensors
    (``initial_attitude: first_sample``) is the accelerometer's direction, which on a moving
    board (a turn's load, a push) is not gravity's: its estimates are withheld
    (``EstimateFlag.UNSETTLED``, counted ``start_check.withheld``) until the
    turn-compensated accelerometer has agreed with it for this long (s), and again whenever
    it disagrees later (the gyro offsets were not measured: ``_start_checked``). None: no
    check."""
    gyro_saturation: Literal["recover", "drop"] = "recover"
    """A gyro sample the chip clipped (flagged SATURATED, perhaps OUT_OF_RANGE too: at its
    stream's full scale): ``recover`` integrates it clipped to the full scale and then pulls
    the tilt back towards the accelerometer with a high gain that decays over ``RECOVERY_S``
    (Fusion's angular-rate recovery), when the rotation ramped into the clip (a clip out
    of a rate well inside the range is dropped either way: RECOVERY_RAMP); ``drop`` skips
    it (a gap in the integration: the
    pipeline counts the clipped frames lost, and the step after them spans the gap at the
    rate after it, ``max_gap_s``). Needs the gyro's stream (``bind``); without one every
    flagged sample is dropped."""


class ImuStep(NamedTuple):
    """What one filter step gets: body NED axes, reference units. (A named tuple: one is
    made per gyro sample, and a frozen dataclass pays an attribute write per field.)"""

    gyro_rad_s: Vec
    accel_g: Vec | None
    """Gravity-positive accelerometer reading in g (level at rest: (0, 0, +1)), or None."""
    mag_ut: Vec | None
    dt_s: float


def _vec(v: Sequence[float]) -> Vec:
    x, y, z = v
    return (float(x), float(y), float(z))


_OK = SampleFlag.OK
_CLIPPED = SampleFlag.SATURATED | SampleFlag.OUT_OF_RANGE | SampleFlag.FILTER_SETTLING
"""The flags a gyro reading the chip cut at its full scale may carry (SATURATED required:
OUT_OF_RANGE alone, beyond the range but not at the rail, is a corrupt word)."""
RECOVERY_S = 3.0
"""Angular-rate recovery: after the last clipped gyro sample, the extra tilt feedback decays
linearly to nothing over this long (s) (Fusion's start-up period)."""
RECOVERY_RAIL = 0.99
"""A clipped gyro sample's axis counts as clipped when its rate is at least this share of
the stream's full scale (the chip's rail is one count short of it)."""
RECOVERY_CHECKED_RAD = 0.05
"""Angular-rate recovery: while the accelerometer disagrees with the attitude by more than
this (rad; 2.9 deg, the complementary filters' soft-gate width of 0.05 g seen as a tilt),
the AHRS withholds its estimates (``EstimateFlag.UNSETTLED``)."""
RECOVERY_RAMP = 0.5
"""Angular-rate recovery: a clipped gyro reading is integrated only when the last rate
measured on a clipped axis, in the clip's direction, was at least this share of the full
scale (or closer to the rail than MAX_ANGULAR_ACCEL_RAD_S2 can cover in one sample period,
where that is the stricter bound): a rotation that reaches the rail ramps into it. Out of a
rate well inside the range the rate would have grown by half the range in one sample
(100,000 deg/s^2 on a 1000 deg/s gyro at 200 Hz, 31,000 on a 250 deg/s gyro at 250 Hz), which
no vehicle does: the reading is a corrupt word or a shock the chip clipped, and it is
dropped (``_ramped_into``)."""
MAX_ANGULAR_ACCEL_RAD_S2 = 500.0
"""The largest angular acceleration taken for a rotation (rad/s^2; 28,600 deg/s^2, a generous
bound for the paragliders and RC aircraft the bundled boards fly): at a slow sample rate or a
small range one sample period at it may span more than the other half of the range, and a
clip out of a rate that far from the rail may then be a real rotation (``_ramped_into``)."""
UNMEASURED_SPAN_CHECK_G = 0.05
"""After a span of unmeasured rotation (``_after_dropped``), the accelerometer checks the
attitude only while it reads within this much of 1 g (g; the soft gate's width): then it
reads gravity, give or take the vibration, and not a manoeuvre's load."""
UNMEASURED_SPAN_CHECKED_RAD = math.radians(5.0)
"""After a span of unmeasured rotation, the attitude counts as checked once the
accelerometer (within UNMEASURED_SPAN_CHECK_G of 1 g) agrees with it within this (rad): the
seed filters' own tilt error in a turbulent cruise (3-4 deg on seed-rc-vario) stays
inside it, the 13 deg an outage left in a pull-up does not."""
SPAN_RESIDUAL_MAX_RAD = math.radians(15.0)
"""After a span of unmeasured rotation, the attitude also counts as checked once the
accelerometer disagrees with it as it did at the last step before the span, within
UNMEASURED_SPAN_CHECKED_RAD (``_span_residual``): a steady disagreement (an accelerometer
offset, the turn compensation's error at the nominal airspeed, the filter's lag behind a
gyro bias) is the filter's own, handed out before the span, not what the span left. Only
when that disagreement was at most this much (rad): beyond it the reading before the span
was no reference."""
SPAN_RESIDUAL_GROWTH_RAD = math.radians(2.0)
"""...and when the disagreement after the span is no larger than before it by more than
this (rad; a turbulent glide's compensated reading scatters by a degree): an error the span
left along the old disagreement adds to it whole, and is held to this."""
UNMEASURED_SPAN_FORCE_G = 0.1
"""Across unfused gyro frames (at most ``max_gap_s``), the specific force in NED the
attitude gives the first accelerometer reading after them may differ from the one it gave
the last reading before them by at most this much in magnitude (g), and in direction by at
most UNMEASURED_SPAN_CHECKED_RAD, for the attitude to count as checked at once
(``_force_continues``): a take-off run's push fades by 0.06 g in 0.15 s on seed-rc-vario."""
UNMEASURED_SPAN_RATE_RAD_S = math.radians(2.0)
"""...and the first gyro rate after them may differ from the last one before them by at
most this (rad/s, each axis): the motion went on as it was. A roll into a coordinated turn
inside the span, which keeps the force's direction in the stale attitude's NED (the
accelerometer cannot see it), leaves a turn rate of g tan(bank) / speed, 0.91 of it about
the body's z axis at the 24.6 deg of bank UNMEASURED_SPAN_FORCE_G lets through: more than
2 deg/s below about 117 m/s."""
START_CHECK_G = 0.05
"""At a start in motion, an accelerometer reading (turn-compensated) is evidence about the
attitude only while it reads within this much of 1 g (g): a turn's load (1.06 g at 20 deg of
bank) or a push reads as a tilt, and says nothing about it."""
START_CHECKED_RAD = math.radians(4.0)
"""At a start in motion, a reading counted as evidence (START_CHECK_G) agrees with the
attitude when it is within this of the gravity the attitude predicts (rad); one that does
not starts the evidence again."""
START_CHECK_RATE_RAD_S = math.radians(3.0)
"""A reading is evidence only while the board turns slower than this (rad/s, the rate's
magnitude): in a coordinated turn the specific force stays along the body's z axis, tilted
from gravity by the bank at a load within START_CHECK_G of 1 g up to 17.7 deg of bank (at
3 deg/s and a paraglider's 10 m/s that bank is 3 deg), and the turn compensation is only as
good as its speed: seed-gps-vario switched on circling, before its wind fit, with turning
readings allowed, handed out attitudes up to 15.7 deg off that its compensated readings
never withdrew."""
_START_RATE_SQ = START_CHECK_RATE_RAD_S * START_CHECK_RATE_RAD_S
START_LOST_RAD = math.radians(6.0)
"""After a start in motion, the attitude stays under watch for the whole run (its gyro
offsets were not measured: seed-gps-vario's MPU-9250 drifted its Madgwick 13 deg off in
7 s of circling after a check it had passed): a reading that can tell and disagrees with it
by more than this (rad) withholds its estimates again until the evidence holds anew."""
START_HOLD_S = 2.0
"""...and a confirmation lasts this long (s) after the last reading that could tell and
agreed: the gyro offsets were not measured, and nothing sees the drift they put into the
attitude while no reading can tell (circling: the watched Madgwick of seed-gps-vario went
from agreeing to 20 deg off in a thermal's turns); at the 1.5 deg/s seed-gps-vario's
unmeasured MPU-9250 drifted, 3 deg."""
START_PULL_GAIN = 2.0
"""While an attitude started in motion is not confirmed, each reading that can tell pulls
its tilt towards the reading's gravity with this gain (rad/s per unit of the sine of the
angle between them; a time constant of 1 s), for a filter that keeps its attitude in
``_q`` (``owns_quaternion``): the filter's own gain, made for a board whose gyro offsets
were measured, may never find the tilt against an unmeasured gyro offset."""
START_CHECK_SHARE = 0.5
"""At a start in motion, the evidence must hold at least this share of the gyro steps of
``start_check_s`` (the readings in between, not evidence either way, are skipped)."""
RECOVERY_GAIN = 10.0
"""Angular-rate recovery: the extra tilt feedback's gain at its start (rad/s per unit of
the sine of the tilt error; Fusion's start-up gain): the tilt error then falls with a time
constant of 0.1 s, growing to the filter's own as the gain decays."""
RESEAT_RATE_RAD_S = 0.5
"""...and a re-seat made while the board turned faster than this (rad/s, the rate's
magnitude) is made once more at the first step slower than it (``_reseat_pending``): the
accelerometer's reading lags a fast rotation by its filters' delay (a few ms: at the
rail's 4.4 rad/s, degrees), and the last re-seat of the test's roll left decoupled 1.8 deg
off, which its own 3 s correction took a second to walk back (worst 0.5-2 s after the roll
1.3 deg; 0.39 with this)."""
_RESEAT_RATE_SQ = RESEAT_RATE_RAD_S * RESEAT_RATE_RAD_S
RESEAT_CHECK_G = UNMEASURED_SPAN_CHECK_G
"""Angular-rate recovery of a filter whose kernel keeps the attitude: the inclination is
re-seated from an accelerometer reading (turn-compensated) only while it reads within this
much of 1 g (g): gravity, give or take the vibration, not a manoeuvre's load."""
_BODY_NED = Frame.BODY_NED
_ACCEL, _MAG, _GYRO = Quantity.ACCEL.value, Quantity.MAG.value, Quantity.GYRO.value
_INF = math.inf
_MAX_FLOAT = sys.float_info.max
TO_G = -1.0 / STANDARD_GRAVITY_M_S2
"""gravity_positive_g's factor (m/s^2 specific force -> gravity-positive g): the same product
for a compiled step's caller."""
NO_VECTOR: Vec = (0.0, 0.0, 0.0)
"""What a compiled step gets for an accel or mag it has none of (with its flag False)."""
KernelReadings = tuple[bool, float, float, float, bool, float, float, float]
"""A compiled step's readings (common/fast_ahrs.py's step form): ``have_a, ax, ay, az,
use_m, mx, my, mz``."""


def kernel_readings(accel_m_s2: Vec | None, mag: Vec | None, use_mag: bool) -> KernelReadings:
    """The readings a compiled per-sample step takes: the accelerometer's specific force
    (m/s^2, body) as the gravity-positive reading (g), the magnetometer field as it is (used
    only with ``use_mag``); an absent one is zeros with its flag False."""
    if accel_m_s2 is None:
        have_a, ax, ay, az = False, 0.0, 0.0, 0.0
    else:
        have_a = True
        ax, ay, az = (accel_m_s2[0] * TO_G, accel_m_s2[1] * TO_G, accel_m_s2[2] * TO_G)
    if mag is None or not use_mag:
        return (have_a, ax, ay, az, False, *NO_VECTOR)
    return (have_a, ax, ay, az, True, *mag)


def rest_columns(diag: FloatArray) -> dict[str, DiagnosticColumn]:
    """The rest detector's columns of a shared row loop's ``diag`` array (columns 3-6,
    common/fast_ahrs.py) as the diagnostics ``at_rest`` and ``rest_gyro_bias_rad_s``
    flatten to."""
    return {"at_rest": diag[:, 3].astype(np.int64), "rest_gyro_bias_rad_s_0": diag[:, 4],
            "rest_gyro_bias_rad_s_1": diag[:, 5], "rest_gyro_bias_rad_s_2": diag[:, 6]}


def _linear_accel_ned(q: Quat, f: Vec) -> Vec:
    """:func:`imuhal.estimation.gravity.linear_accel_ned_m_s2` on plain floats (R(q) f + g):
    the same rotation, without building two numpy arrays per step."""
    w, x, y, z = q
    fx, fy, fz = f
    # each product once (the same values as writing them out in every entry)
    ww, xx, yy, zz = w * w, x * x, y * y, z * z
    xy, wz, xz, wy, yz, wx = x * y, w * z, x * z, w * y, y * z, w * x
    return (
        (ww + xx - yy - zz) * fx + 2 * (xy - wz) * fy + 2 * (xz + wy) * fz,
        2 * (xy + wz) * fx + (ww - xx + yy - zz) * fy + 2 * (yz - wx) * fz,
        2 * (xz - wy) * fx + 2 * (yz + wx) * fy + (ww - xx - yy + zz) * fz
        + STANDARD_GRAVITY_M_S2,
    )


def _linear_accel_ned_rows(q: FloatArray, f: FloatArray) -> FloatArray:
    """:func:`_linear_accel_ned` for (m, 4) quaternions and (m, 3) specific forces: the same
    products in the same order, so the same floats (NaN rows where ``f`` is NaN)."""
    w, x, y, z = q[:, 0], q[:, 1], q[:, 2], q[:, 3]
    fx, fy, fz = f[:, 0], f[:, 1], f[:, 2]
    ww, xx, yy, zz = w * w, x * x, y * y, z * z
    xy, wz, xz, wy, yz, wx = x * y, w * z, x * z, w * y, y * z, w * x
    return np.column_stack((
        (ww + xx - yy - zz) * fx + 2 * (xy - wz) * fy + 2 * (xz + wy) * fz,
        2 * (xy + wz) * fx + (ww - xx + yy - zz) * fy + 2 * (yz - wx) * fz,
        2 * (xz - wy) * fx + 2 * (yz + wx) * fy + (ww - xx - yy + zz) * fz
        + STANDARD_GRAVITY_M_S2,
    ))


MIN_KERNEL_FRAMES = 8
"""Gyro frames from which a fusion step's blocks go through the compiled row kernel when the
frames one by one would run the Python step: below, the kernel's call and the bookkeeping on
arrays (about 45 us a step) cost more than the frames one by one (Madgwick, numba's JIT row
kernel, 7.3 us a frame one by one: 7.9 against 7.3 us a frame at 8 frames, 5.0 against 7.4 at
16; ``python -m tests.benchmarks.bench_block_parts kernel``)."""
MIN_KERNEL_FRAMES_COMPILED_STEP = 32
"""The same where the frames one by one run the compiled per-sample step (the AOT extension,
or ``IMUHAL_KERNELS=jit``), about 3.7 us a frame: 4.1 against 3.8 at 24 frames, 3.4 against
3.7 at 32, 2.3 against 3.7 at 64."""
MIN_BLOCK_STEP_FRAMES = 3
"""The same where the filter has a compiled block step (``_block_step``: the bookkeeping,
turn compensation and gravity-compensated acceleration inside the one call; Madgwick,
numba's JIT, against the Python step frame by frame, us a frame: 10.7 against 9.0 at 2
frames, 7.9 against 8.9 at 3, 3.7 against 8.6 at 8, 2.6 against 9.0 at 16; ``python -m
tests.benchmarks.bench_block_parts kernel``, load 10-20)."""
_ROWS_LINEAR_FROM = 24
"""Kernel rows from which the estimates' gravity-compensated acceleration is computed on
arrays (``_linear_accel_ned_rows``, about 38 us a call for any size) rather than row by
row on floats (``_linear_accel_ned``, about 1.4 us a row): the same floats either way."""
_HEAD_FRAMES = 16
"""Gyro frames handed over one by one first while an AHRS is not aligned yet."""


def _head(blocks: Sequence[Block], gyro: Block, frames: int
          ) -> tuple[list[Block], list[Block]]:
    """``blocks`` cut before the time of ``gyro``'s frame ``frames``: the frames before it
    and the rest (all in the head when there is no such cut)."""
    t = gyro.t_ns
    if len(t) <= frames or t[frames] == t[0]:
        return list(blocks), []
    cut = t[frames]
    head = [h for b in blocks if (h := b.select(b.t_ns < cut)) is not None]
    rest = [r for b in blocks if (r := b.select(b.t_ns >= cut)) is not None]
    return head, rest


def _tilt_pulled(q: Quat, accel_g: Vec, angle_gain: float) -> tuple[Quat, float]:
    """``q`` (body -> NED) turned so the gravity it predicts in the body frame moves towards
    the measured gravity-positive ``accel_g`` by ``angle_gain`` times the sine of the angle
    between them (the Mahony / Fusion accelerometer feedback, integrated over one step), and
    the angle between the predicted and the measured gravity left after the turn (rad, to
    first order; infinite for a zero reading)."""
    ax, ay, az = accel_g
    norm = math.sqrt(ax * ax + ay * ay + az * az)
    if not norm > 0.0:
        return q, _INF
    ax, ay, az = ax / norm, ay / norm, az / norm
    w, x, y, z = q
    # gravity's direction in the body frame as q predicts it: R(q)^T (0, 0, 1)
    vx, vy, vz = 2 * (x * z - w * y), 2 * (y * z + w * x), w * w - x * x - y * y + z * z
    # the body rotation that turns the prediction towards the measurement
    ex, ey, ez = ay * vz - az * vy, az * vx - ax * vz, ax * vy - ay * vx
    apart = math.atan2(math.sqrt(ex * ex + ey * ey + ez * ez), ax * vx + ay * vy + az * vz)
    angle = angle_gain * math.sqrt(ex * ex + ey * ey + ez * ez)
    hx, hy, hz = 0.5 * angle_gain * ex, 0.5 * angle_gain * ey, 0.5 * angle_gain * ez
    w, x, y, z = (w - x * hx - y * hy - z * hz, x + w * hx + y * hz - z * hy,
                  y - x * hz + w * hy + z * hx, z + x * hy - y * hx + w * hz)
    n = math.sqrt(w * w + x * x + y * y + z * z)
    return (w / n, x / n, y / n, z / n), max(0.0, apart - angle)


def _disagreement(q: Quat, accel_g: Vec) -> Vec:
    """How the gravity-positive reading ``accel_g`` disagrees with the gravity ``q``
    predicts, in the body frame: the cross product of the two unit vectors (the axis that
    turns the prediction towards the reading, times the sine of the angle between them), as
    ``_tilt_pulled`` turns it; zero for a zero reading."""
    ax, ay, az = accel_g
    norm = math.sqrt(ax * ax + ay * ay + az * az)
    if not norm > 0.0:
        return NO_VECTOR
    ax, ay, az = ax / norm, ay / norm, az / norm
    w, x, y, z = q
    vx, vy, vz = 2 * (x * z - w * y), 2 * (y * z + w * x), w * w - x * x - y * y + z * z
    return (ay * vz - az * vy, az * vx - ax * vz, ax * vy - ay * vx)


class AhrsEstimator(Estimator):
    """An attitude estimator stepped once per gyro sample. See the module docstring."""

    Settings: ClassVar[type[EstimatorSettings]] = AhrsSettings
    consumes: ClassVar[tuple[type, ...]] = (GyroSample, AccelSample, MagSample,
                                            VelocitySample, AirspeedSample, StreamGap)
    uses_mag: ClassVar[bool] = True
    owns_quaternion: ClassVar[bool] = True
    """The kernel steps from ``_q`` (it keeps no attitude of its own): the angular-rate
    recovery can pull its tilt. False for a wrapper whose kernel holds the attitude (the
    recovery then re-seats the kernel's inclination from the accelerometer instead:
    ``_reseat_tilt``, which such a filter implements)."""

    settings: AhrsSettings
    _gyro_range_rad_s: float | None = None
    """The bound gyro stream's full scale (rad/s), where clipped samples are cut."""
    _q: Quat

    # ------------------------------------------------------------------ subclass hooks
    @abstractmethod
    def _reset_filter(self) -> None:
        """Initial filter state, including ``self._q``."""

    @abstractmethod
    def _step(self, step: ImuStep) -> dict[str, Any] | None:
        """Advance one gyro sample; return per-step diagnostics, or None for "no estimate yet"."""

    @abstractmethod
    def _filter_state(self) -> dict[str, Any]:
        """JSON-serialisable filter internals (the quaternion is saved by the base)."""

    @abstractmethod
    def _set_filter_state(self, state: dict[str, Any]) -> None:
        """Restore what ``_filter_state`` returned."""

    # ------------------------------------------------------------------ Estimator API
    def reset(self) -> None:
        self._accel_m_s2: Vec | None = None
        self._accel_t_ns: int | None = None
        self._mag_ut: Vec | None = None
        self._mag_t_ns: int | None = None
        self._last_gyro_t_ns: int | None = None
        self._counters: dict[str, Any] = {
            "steps": 0,
            "invalid": {c.value: 0 for c in (Quantity.GYRO, Quantity.ACCEL, Quantity.MAG)},
            "dt_fallbacks": 0,
            "stale_accel": 0,
            "stale_mag": 0,
            "beyond_full_scale": {Quantity.GYRO.value: 0, Quantity.ACCEL.value: 0},
            "angular_rate_recovery": {"clipped_samples": 0, "recoveries": 0, "withheld": 0},
            "start_check": {"withheld": 0, "confirmed_after_s": None},
        }
        self._recovery_left_s = 0.0
        self._reseat_pending = False
        """A re-seat (``_reseat``) was made from a reading in a fast rotation: one more is
        due at the first slow step of the recovery."""
        self._recovery_apart_rad = _INF
        """The angle between the predicted and the measured gravity at the recovery's last
        pull (rad; infinite before the first)."""
        self._last_rate: Vec = NO_VECTOR
        """The last gyro rate measured (not clipped), rad/s body: what a clip must have
        ramped out of (``_ramped_into``)."""
        self._dropped_after_ns: int | None = None
        """Set when gyro frames went unfused (dropped invalid, or counted lost): the time
        stamp of the last step before them, then (``_unchecked``) kept until the
        accelerometer has checked the attitude; None: every rotation was measured."""
        self._unchecked = False
        """The attitude missed more than ``max_dt_s`` of rotation and the accelerometer has
        not confirmed it since: estimates are withheld (``_after_dropped``)."""
        self._step_accel: Vec | None = None
        """The accelerometer reading (m/s^2, body) the last gyro step had, None when it had
        none fresh (``_span_starts``)."""
        self._span_residual: Vec | None = None
        """While the attitude is unchecked after a span (``_after_dropped``): how the
        accelerometer reading at the last step before the span, compensated as the filter
        fuses it, disagreed with the gravity the checked attitude predicted (body frame,
        the cross product of the two unit vectors: the axis times the sine of the angle
        between them); None: that reading was no reference (not within
        UNMEASURED_SPAN_CHECK_G of 1 g, or apart by more than SPAN_RESIDUAL_MAX_RAD)."""
        self._span_before: tuple[Vec, Vec, int] | None = None
        """Before unfused gyro frames, while the attitude was checked: the specific force
        in NED (m/s^2) it gave the last accelerometer reading, the last gyro rate measured
        (rad/s, body) and the last step's time stamp (ns): what the first readings after
        them are compared with (``_force_continues``); None: no such readings."""
        self._start_watched = False
        """Aligned from the sensors at a start not known still: every step is checked
        (``_start_checked``), for the whole run."""
        self._start_unchecked = False
        """Watched and not confirmed (or no longer): estimates are withheld."""
        self._moving_at_start = False
        """The pipeline says the board moved at switch-on (``moving_at_start``): the start
        is checked."""
        self._start_since_ns: int | None = None
        """The time stamp of the first reading of the evidence gathered so far (None:
        none)."""
        self._start_readings = 0
        """Readings of the evidence gathered so far."""
        self._start_agreed_ns = 0
        """The time stamp of the last reading that could tell and agreed (ns)."""
        self._q = IDENTITY
        identity = self.settings.initial_attitude == "identity"
        self._tilt_aligned = identity
        self._heading_aligned = identity or not self.uses_mag
        self._kinematics = KinematicAcceleration(self.settings)
        self._turn_on = bool(self.settings.turn_compensation)
        # no speed source (nominal, velocity, airspeed) yet: no turn to compensate, and the
        # compiled step's caller can skip KinematicAcceleration.step (_on_gyro)
        self._no_speed = self.settings.nominal_airspeed_m_s is None
        # turns compensated by the nominal airspeed alone (no velocity or airspeed sample
        # yet): the other case _on_gyro writes out for the compiled step
        self._nominal_only = self._turn_on and not self._no_speed
        # an infinite full scale still rejects +-inf: the largest float is "unbounded, finite"
        self._gyro_fs = min(float(self.settings.gyro_full_scale_rad_s), _MAX_FLOAT)
        self._accel_fs = min(float(self.settings.accel_full_scale_m_s2), _MAX_FLOAT)
        # read at every gyro sample: kept as plain attributes
        self._nominal_dt_s = self.settings.sample_period_s
        self._dt_from_timestamps = self.settings.dt_from_timestamps
        self._max_dt_s = self.settings.max_dt_s
        self._max_gap_s = self.settings.max_gap_s
        self._gap_at_ns: int | None = None
        """The time stamp of the gyro frame a counted loss precedes (a StreamGap)."""
        self._max_aux_age_s = self.settings.max_aux_age_s
        self._rows_chosen = False  # the row kernel's backend: chosen again at its next use
        self._rest: tuple[float, ...] = REST_START
        """The rest detector's state (``common/fast_ahrs.rest_update``)."""
        self._rest_params = (rest_params(self.settings)
                             if isinstance(self.settings, RestSettings) else REST_OFF)
        self._rest_on = self._rest_params[0] == 1.0
        self._at_rest = False
        """The rest detector's verdict at the last step (the step's soft gate is off)."""
        self._reset_filter()

    def bind(self, streams: Sequence[StreamSpec]) -> None:
        """Gyro and accelerometer limits from the streams' full scales (+10 % for
        calibration gains) and ``sample_period_s`` from the gyro stream's rate, unless given
        by hand; a hand setting that contradicts its stream raises StreamContradiction
        (imuhal.estimation.streams)."""
        gyro = stream_of(streams, Quantity.GYRO)
        self._gyro_range_rad_s = None if gyro is None else gyro.full_scale
        bound = bound_settings(self, streams, period_key="sample_period_s")
        if bound is not self.settings:
            self.settings = bound
            self.reset()
        self._load_kernels()

    def _load_kernels(self) -> None:
        """Load the compiled row kernel and block step now, when the run starts (the
        pipeline binds its estimators before the first read), not at the first block of
        several frames: without an AOT extension that is numba compiling or loading them
        from its cache, seconds of pause and about 120 MB once per process. In the middle of
        a flight (the first read after a stall or a burst of bus errors brings several
        frames) the pause held every device up: the seed board's one-hour soak loaded numba
        at 61 s. Loading them changes no path: the backend and the kernels chosen are the
        same, only when (``_rows_kernel``, ``_has_block_step``)."""
        self._rows_kernel()
        self._has_block_step()

    def process(self, item: Sample | Estimate) -> list[Estimate]:
        # The pipeline calls this for every sample (three per IMU tick): the common samples
        # take a direct path (exact type, one bound check per component); anything else,
        # subclasses of the sample types included, takes the general one below.
        kind = type(item)
        if kind is AccelSample:
            # the most frequent non-gyro sample, on its own path: its field read directly
            # (the ``vector`` property is a call), one bound check per component
            if item.flags != _OK:  # type: ignore[union-attr]  # narrowed by `type(item) is` through a local (the hot path): mypy does not follow it
                self._counters["invalid"][_ACCEL] += 1
                return []
            x, y, z = item.accel_m_s2  # type: ignore[union-attr]  # narrowed by `type(item) is` through a local (the hot path): mypy does not follow it
            fs = self._accel_fs
            if not (-fs <= x <= fs and -fs <= y <= fs and -fs <= z <= fs):
                self._reject(_ACCEL)  # NaN and +-inf fail the comparisons too
                return []
            if item.frame is not _BODY_NED:  # type: ignore[union-attr]  # narrowed by `type(item) is` through a local (the hot path): mypy does not follow it
                return self._wrong_frame(item)  # type: ignore[arg-type]  # narrowed by `type(item) is` through a local (the hot path): mypy does not follow it
            self._accel_m_s2, self._accel_t_ns = (float(x), float(y), float(z)), item.t_ns
            return []
        if kind is MagSample:
            return self._on_mag(item)  # type: ignore[arg-type]  # narrowed by `type(item) is` through a local (the hot path): mypy does not follow it
        if kind is GyroSample:
            if item.flags != _OK:  # type: ignore[union-attr]  # narrowed by `type(item) is` through a local (the hot path): mypy does not follow it
                return self._flagged_gyro(item)  # type: ignore[arg-type]  # narrowed by `type(item) is` through a local (the hot path): mypy does not follow it
            x, y, z = item.gyro_rad_s  # type: ignore[union-attr]  # narrowed by `type(item) is` through a local (the hot path): mypy does not follow it
            fs = self._gyro_fs
            if not (-fs <= x <= fs and -fs <= y <= fs and -fs <= z <= fs):
                self._reject(_GYRO)
                return []
            if item.frame is not _BODY_NED:  # type: ignore[union-attr]  # narrowed by `type(item) is` through a local (the hot path): mypy does not follow it
                return self._wrong_frame(item)  # type: ignore[arg-type]  # narrowed by `type(item) is` through a local (the hot path): mypy does not follow it
            rate = self._last_rate = (float(x), float(y), float(z))
            if self._start_watched or not self._tilt_aligned:
                return self._start_checked(item, rate)  # type: ignore[arg-type]  # narrowed by `type(item) is` through a local (the hot path): mypy does not follow it
            if self._dropped_after_ns is not None:
                return self._after_dropped(item, rate)  # type: ignore[arg-type]  # narrowed by `type(item) is` through a local (the hot path): mypy does not follow it
            if self._recovery_left_s > 0.0:
                return self._recovering(item, rate)  # type: ignore[arg-type]  # narrowed by `type(item) is` through a local (the hot path): mypy does not follow it
            return self._on_gyro(item, rate)  # type: ignore[arg-type]  # narrowed by `type(item) is` through a local (the hot path): mypy does not follow it
        return self._process_general(item)

    def _on_mag(self, item: MagSample) -> list[Estimate]:
        """A magnetometer sample (exact type, ``process``'s direct path): kept for the next
        gyro step when valid, finite and in the body NED frame and the filter uses it."""
        if item.flags != _OK:
            self._counters["invalid"][_MAG] += 1
            return []
        x, y, z = item.mag_ut
        # the magnetometer's scale is unbounded: only finite (NaN fails every test)
        if not (abs(x) < _INF and abs(y) < _INF and abs(z) < _INF):
            self._reject(_MAG)
            return []
        if item.frame is not _BODY_NED:
            return self._wrong_frame(item)
        if self.uses_mag:
            self._mag_ut, self._mag_t_ns = (float(x), float(y), float(z)), item.t_ns
        return []

    # ------------------------------------------------------------------ angular-rate recovery
    def _flagged_gyro(self, item: GyroSample) -> list[Estimate]:
        """A gyro sample flagged invalid: dropped and counted, unless it is a reading the
        chip clipped at its full scale, ``gyro_saturation`` is ``recover`` and the rotation
        ramped into the clip (``_ramped_into``): then the rotation goes on beyond the range,
        and integrating the clipped rate loses less than a gap. A clip out of a rate well
        inside the range is no rotation (a corrupt word or a shock the chip clipped): it is
        dropped as any invalid sample, and counted ``unramped_clips`` besides."""
        limit = self._gyro_range_rad_s
        if (limit is None or not item.flags & SampleFlag.SATURATED or item.flags & ~_CLIPPED
                or item.frame is not _BODY_NED or self.settings.gyro_saturation != "recover"):
            return self._dropped_gyro()
        x, y, z = item.gyro_rad_s
        if not (abs(x) < _INF and abs(y) < _INF and abs(z) < _INF):
            return self._dropped_gyro()
        clipped = (min(max(float(x), -limit), limit), min(max(float(y), -limit), limit),
                   min(max(float(z), -limit), limit))
        counts = self._counters["angular_rate_recovery"]
        if not self._ramped_into(clipped, limit):
            counts["unramped_clips"] = counts.get("unramped_clips", 0) + 1
            return self._dropped_gyro()
        counts["clipped_samples"] += 1
        if self._recovery_left_s <= 0.0:
            counts["recoveries"] += 1
            self._recovery_apart_rad = _INF
            self._reseat_pending = False
        self._recovery_left_s = RECOVERY_S
        if self._dropped_after_ns is not None:  # unchecked or unmeasured: as any step
            return self._after_dropped(item, clipped)
        return self._recovering(item, clipped)

    def _dropped_gyro(self) -> list[Estimate]:
        """An invalid gyro sample that is no clipped rate: dropped and counted, and the
        span it leaves unmeasured remembered for the next valid one (``_after_dropped``)."""
        self._counters["invalid"][_GYRO] += 1
        if self._dropped_after_ns is None:
            self._span_starts()
        return []

    def _span_starts(self) -> None:
        """Gyro frames go unfused after the last step: remember when, and the specific
        force in NED the (checked) attitude gave the accelerometer reading of that step
        (``_force_continues``). A counted loss is known only at its end, when the readings
        after it may have come in, so it is that step's reading, not the newest."""
        self._dropped_after_ns = last = self._last_gyro_t_ns
        accel = self._step_accel
        self._span_before = None
        if not self._unchecked:
            self._span_residual = None  # a new span: the attitude is checked, compare anew
        if accel is None or last is None or self._unchecked or not self._tilt_aligned:
            return
        self._span_residual = self._residual_of(self._compensated_g(accel, last,
                                                                    self._last_rate))
        x, y, z = _linear_accel_ned(self._q, accel)
        self._span_before = ((x, y, z - STANDARD_GRAVITY_M_S2), self._last_rate, last)

    def _after_dropped(self, item: GyroSample, rate: Vec) -> list[Estimate]:
        """A valid gyro sample after gyro frames that went unfused (dropped invalid, or
        counted lost: a StreamGap). Up to ``max_dt_s`` since the last step the filter goes
        on as usual. Longer, the rotation in between went unmeasured (the step after a
        counted loss integrates its true interval at the rate after it, which misses how
        the rate went meanwhile): the attitude is unchecked, and its estimates are withheld
        (UNSETTLED, counted ``unmeasured_withheld``) until the accelerometer, while it reads
        within UNMEASURED_SPAN_CHECK_G of 1 g, agrees with it within
        UNMEASURED_SPAN_CHECKED_RAD, or at once when the first accelerometer reading after a
        counted loss of at most ``max_gap_s`` shows the same specific force in NED as the last
        one before it (``_force_continues``).

        Found by the soak (seed-rc-vario, issue 26): a MAX21105 answering all ones for
        0.5 s during a pull-up lost 13 deg of pitch (33 deg turned, 25 integrated at the
        rate after the gap); in the turbulent aerobatics that followed, the accelerometer
        rarely read 1 g, the Madgwick filter took about a minute to find its tilt again,
        and the vario, fed the wrong vertical acceleration, gave 116 climb rates more than
        3 m/s off in 300 s with nothing flagged. Withheld, the vario predicts those
        intervals without acceleration and withholds its own estimates until the altitudes
        have settled its climb rate (vario-kf3). Pulling the tilt towards the accelerometer
        about every axis, as after a clip (Fusion's recovery), was tried: in the pull-up's
        2.4 g it turned the attitude 60 deg off."""
        last = self._dropped_after_ns
        counts = self._counters["angular_rate_recovery"]
        if not self._unchecked:
            self._dropped_after_ns = None
            if last is None or (item.t_ns - last) * _NS <= self._max_dt_s \
                    or not self._tilt_aligned:
                self._span_before = None
                if self._recovery_left_s > 0.0:
                    return self._recovering(item, rate)
                return self._on_gyro(item, rate)
            self._unchecked = True
            self._dropped_after_ns = last
            counts["unmeasured_spans"] = counts.get("unmeasured_spans", 0) + 1
            if (item.t_ns - last) * _NS > self._max_gap_s:
                self._span_before = None  # stepped over at the nominal period: no span
        out = self._recovering(item, rate) if self._recovery_left_s > 0.0 \
            else self._on_gyro(item, rate)
        if not out:
            return out
        continues = self._force_continues(rate)
        if continues or self._accel_confirms(item.t_ns, rate):
            if continues:
                counts["unmeasured_continued"] = counts.get("unmeasured_continued", 0) + 1
            self._unchecked = False
            self._dropped_after_ns = None
            self._span_before = None
            self._span_residual = None
            return out
        counts["unmeasured_withheld"] = counts.get("unmeasured_withheld", 0) + 1
        return [RejectedEstimate(t_ns=item.t_ns, source=self.instance, kind="attitude",
                                 flags=EstimateFlag.UNSETTLED, estimator=self.name)]

    def _force_continues(self, rate: Vec) -> bool:
        """Whether the motion went on across the unfused span as it was: the gyro ``rate``
        after it is the one before it within UNMEASURED_SPAN_RATE_RAD_S, and the first
        accelerometer reading after the one it was compared with (``_span_before``), taken
        within a nominal period of this step, gives through the attitude the same specific
        force in NED as that one did, within UNMEASURED_SPAN_FORCE_G in magnitude and
        UNMEASURED_SPAN_CHECKED_RAD in direction. Asked once per span: the comparison is
        used up by the first such reading, whatever it says.

        Why it checks the attitude: a tilt error E left by the span turns every specific
        force the attitude puts in NED by E, so a force that went on across the span (a
        take-off run's push, a glide's 1 g) comes out turned by E after it; an attitude
        that missed a rotation about any axis but the force's own shows as a turn. What
        the force cannot see: a force that turned by exactly the rotation the attitude
        missed and kept its magnitude within UNMEASURED_SPAN_FORCE_G (a roll into a
        coordinated turn of up to 24.6 deg of bank inside the span: 1/cos(bank) g; the
        confirmation by a 1 g reading has the same blind spot up to 17.7 deg), which the
        turn rate it leaves gives away (UNMEASURED_SPAN_RATE_RAD_S); and a rotation about
        the force (its heading, when the force is gravity alone: no tilt)."""
        span, accel, t_ns = self._span_before, self._accel_m_s2, self._accel_t_ns
        if span is None or accel is None or t_ns is None or t_ns <= span[2] \
                or self._last_gyro_t_ns is None \
                or (self._last_gyro_t_ns - t_ns) * _NS > self._nominal_dt_s:
            return False
        self._span_before = None
        (bx, by, bz), rate_before, _ = span
        limit = UNMEASURED_SPAN_RATE_RAD_S
        if not all(abs(a - b) <= limit for a, b in zip(rate, rate_before, strict=True)):
            return False
        x, y, z = _linear_accel_ned(self._q, accel)
        z -= STANDARD_GRAVITY_M_S2
        n_after = math.sqrt(x * x + y * y + z * z)
        n_before = math.sqrt(bx * bx + by * by + bz * bz)
        if abs(n_after - n_before) > UNMEASURED_SPAN_FORCE_G * STANDARD_GRAVITY_M_S2 \
                or not n_after > 0.0 or not n_before > 0.0:
            return False
        cx, cy, cz = y * bz - z * by, z * bx - x * bz, x * by - y * bx
        apart = math.atan2(math.sqrt(cx * cx + cy * cy + cz * cz), x * bx + y * by + z * bz)
        return apart <= UNMEASURED_SPAN_CHECKED_RAD

    def _accel_confirms(self, t_ns: int, rate: Vec) -> bool:
        """The newest accelerometer reading, fresh and less the kinematic acceleration of
        the step (``_checking_g``), is within UNMEASURED_SPAN_CHECK_G of 1 g and within
        UNMEASURED_SPAN_CHECKED_RAD of the gravity the attitude predicts."""
        g = self._checking_g(t_ns, rate)
        if g is None or abs(math.sqrt(g[0] * g[0] + g[1] * g[1] + g[2] * g[2]) - 1.0) > \
                UNMEASURED_SPAN_CHECK_G:
            return False
        if _tilt_pulled(self._q, g, 0.0)[1] <= UNMEASURED_SPAN_CHECKED_RAD:
            return True
        before = self._span_residual
        if before is None:
            return False
        now = _disagreement(self._q, g)
        # as before within 5 deg, and no larger than before but for the reading's noise: an
        # error the span added along the old disagreement shows whole in its size
        return math.dist(now, before) <= math.sin(UNMEASURED_SPAN_CHECKED_RAD) and \
            math.hypot(*now) <= math.hypot(*before) + math.sin(SPAN_RESIDUAL_GROWTH_RAD)

    def _residual_of(self, g: Vec | None) -> Vec | None:
        """``_span_residual`` of the compensated reading ``g`` (gravity-positive g)."""
        if g is None or abs(math.sqrt(g[0] * g[0] + g[1] * g[1] + g[2] * g[2]) - 1.0) > \
                UNMEASURED_SPAN_CHECK_G:
            return None
        e = _disagreement(self._q, g)
        if math.sqrt(e[0] * e[0] + e[1] * e[1] + e[2] * e[2]) > \
                math.sin(SPAN_RESIDUAL_MAX_RAD):
            return None
        return e

    def _checking_g(self, t_ns: int, rate: Vec) -> Vec | None:
        """What checks the attitude at the gyro step at ``t_ns`` with the ``rate`` (rad/s,
        body): the newest accelerometer reading if fresh (``max_aux_age_s``), less the
        kinematic acceleration the filter's own step removes from it (turn compensation:
        ``rate`` x the airspeed along the body's x axis, which does not depend on the
        attitude), as a gravity-positive reading in g; None: no fresh reading.

        Compensated, as the filter fuses it: in a turn the raw reading is the load factor
        along the body's z axis (1.1 g at 25 deg of bank), which is neither 1 g nor
        gravity's direction, so a check of the raw reading never passed while circling
        (gy91's 300 s soak: an attitude withheld for 33 s of a thermal after a 2 s IMU
        outage), and a recovery's pull towards it turned the tilt towards the bank."""
        accel, a_t = self._accel_m_s2, self._accel_t_ns
        if accel is None or a_t is None or (
                self._max_aux_age_s is not None and (t_ns - a_t) * _NS > self._max_aux_age_s):
            return None
        return self._compensated_g(accel, t_ns, rate)

    def _compensated_g(self, accel: Vec, t_ns: int, rate: Vec) -> Vec:
        """``accel`` (m/s^2, body) less the kinematic acceleration of the step at ``t_ns``
        with ``rate`` (turn compensation), as a gravity-positive reading in g."""
        if self._turn_on:
            kinematic = self._kinematics.acceleration(t_ns, rate)[1]
            if kinematic != NO_VECTOR:
                accel = compensated(accel, kinematic)
        return gravity_positive_g(accel)

    def _ramped_into(self, clipped: Vec, limit: float) -> bool:
        """Whether a reading clipped at +-``limit`` (rad/s) can be a rotation that reached
        the rail: on some axis at the rail (RECOVERY_RAIL) the last rate measured, in the
        clip's direction, was at least RECOVERY_RAMP of the range, or within what
        MAX_ANGULAR_ACCEL_RAD_S2 covers in one sample period of the rail where that is the
        looser bound (a slow gyro or a small range).

        Why: a vehicle's rate is continuous and its angular acceleration bounded, so a
        rotation beyond the range passes through the upper part of it first, and the
        chip's rate filter smooths it on the way. A word at the rail straight out of a rate
        well inside the range is a corrupt word or a shock, not a turn: integrated at the
        full scale it put up to the range times the step into the attitude, and the
        recovery's pull then had to find it again against an accelerometer reading
        whatever the vehicle's acceleration was (in the ``thermal`` launch run its push:
        the fault matrix at 10 % ``wild_value`` handed out 220 of 923 attitudes on gy91 and
        123 of 295 on seed-gps-vario more than 10 deg off, worst 29.5 deg). Dropped, the
        clip is a gap the next measured rate spans (``_after_dropped``)."""
        rail = RECOVERY_RAIL * limit
        ramp = min(RECOVERY_RAMP * limit, rail - MAX_ANGULAR_ACCEL_RAD_S2 * self._nominal_dt_s)
        return any(abs(c) >= rail and (r if c > 0.0 else -r) >= ramp
                   for c, r in zip(clipped, self._last_rate, strict=True))

    def _recovering(self, item: GyroSample, rate: Vec) -> list[Estimate]:
        """One gyro step during the angular-rate recovery (Fusion's): before the filter's own
        step, the tilt is pulled towards the newest accelerometer reading about every axis
        with the recovery gain (decaying linearly from RECOVERY_GAIN to 0 over RECOVERY_S
        after the last clipped sample); the filter's step then runs as usual. Every clip
        it follows ramped into the rail (``_ramped_into``): the rotation went on beyond the
        range by an amount nobody measured, about any axis (what it missed about one axis
        turns the others' integration), so the pull is neither limited to the clipped axes
        nor to an amount. While the accelerometer disagrees with the attitude the step
        hands out by more than RECOVERY_CHECKED_RAD, or no fresh reading (``max_aux_age_s``)
        that is gravity (``_reads_gravity``) checks it, the estimates are withheld
        (UNSETTLED): the attitude is not known yet.
        A filter whose kernel keeps the attitude (not ``owns_quaternion``: decoupled, VQF)
        cannot be pulled: its inclination is re-seated from the accelerometer instead
        (``_reseat``: Fusion's recovery with the gain at its limit). An attitude still
        unconfirmed when the recovery runs out stays withheld until the accelerometer agrees
        (``_after_dropped``'s check)."""
        last = self._last_gyro_t_ns
        dt = self._nominal_dt_s
        if last is not None and 0.0 < (item.t_ns - last) * _NS <= self._max_dt_s:
            dt = (item.t_ns - last) * _NS
        gain = RECOVERY_GAIN * self._recovery_left_s / RECOVERY_S
        self._recovery_left_s = max(0.0, self._recovery_left_s - dt)
        g = self._checking_g(item.t_ns, rate) if self._tilt_aligned else None
        if g is not None and not self._reads_gravity(g):
            # not gravity: neither pulls nor confirms (seed board, 8 s tumble: Madgwick pulled
            # towards a pitch's reading the nominal airspeed's compensation had bent, and a
            # 3.4 g reading confirmed it, 14.3 deg off)
            g = None
        if g is not None:
            if self.owns_quaternion:
                self._q = _tilt_pulled(self._q, g, gain * dt)[0]
            else:
                self._reseat(g, rate)
        out = self._on_gyro(item, rate)
        # judged on the attitude the step hands out, not the one before it: the step
        # integrated the clipped rate, which is what may be wrong (a wild gyro word clipped
        # at the rail in the first read after a 46 ms host stall put 45 deg of pitch in one
        # step and was handed out; fault matrix, seed-gps-vario, 10 %); no fresh reading:
        # an earlier agreement no longer holds
        self._recovery_apart_rad = _INF if g is None else _tilt_pulled(self._q, g, 0.0)[1]
        if out and self._recovery_apart_rad > RECOVERY_CHECKED_RAD:
            if self._recovery_left_s <= 0.0:
                # the recovery ends with the attitude still unconfirmed (a filter whose
                # kernel keeps the attitude gets no pull: decoupled, after a roll beyond
                # its range, was 168 deg off when the recovery ran out and handed that
                # out): from here it is checked as after an unmeasured span
                self._unchecked = True
                self._dropped_after_ns = self._last_gyro_t_ns
                self._span_before = self._span_residual = None
            self._counters["angular_rate_recovery"]["withheld"] += 1
            return [RejectedEstimate(t_ns=item.t_ns, source=self.instance, kind="attitude",
                                     flags=EstimateFlag.UNSETTLED, estimator=self.name)]
        return out

    def _reads_gravity(self, g: Vec) -> bool:
        """Whether the compensated reading ``g`` (gravity-positive g, ``_checking_g``) can
        pull or confirm the attitude during a recovery: it reads within RESEAT_CHECK_G of
        1 g, and the turn compensation moved it by at most RESEAT_CHECK_G (the raw reading
        says the same).

        Why the magnitude: a reading far from 1 g holds a manoeuvre's load, whose direction
        is not gravity's (a tumble's pitch read 3.4 g compensated, and agreed in direction
        with an attitude 14 deg off). Why the raw reading: the compensation's model (a turn
        flown forward at the airspeed) is not what a tumble does: the seed board's nominal
        10 m/s at a 2 rad/s pitch turned a reading upside down within 0.05 g of 1 g (a
        re-seat from it put VQF 175 deg off), and the raw reading in a turn is the load, not
        gravity. A recovery in a coordinated turn then gets no pull and stays withheld until
        the turn ends or the recovery runs out (then ``_after_dropped``'s check)."""
        gx, gy, gz = g
        if abs(math.sqrt(gx * gx + gy * gy + gz * gz) - 1.0) > RESEAT_CHECK_G:
            return False
        raw = self._accel_m_s2
        assert raw is not None  # g is its fresh reading, compensated
        rx, ry, rz = gravity_positive_g(raw)
        return (rx - gx) ** 2 + (ry - gy) ** 2 + (rz - gz) ** 2 <= RESEAT_CHECK_G * RESEAT_CHECK_G

    def _reseat(self, g: Vec, rate: Vec) -> None:
        """The recovery's pull for a filter whose kernel keeps the attitude (not
        ``owns_quaternion``): while the compensated reading ``g`` (gravity-positive g, which
        ``_reads_gravity`` passed) disagrees with the attitude by more than
        RECOVERY_CHECKED_RAD, the kernel's inclination starts again from it, its
        heading kept (``_reseat_tilt``), counted ``reseats``.

        Why not the pull: the kernel's attitude is its own state (decoupled: a strapdown
        and an accelerometer filter in an almost-inertial frame; VQF the same), which the
        base cannot turn a little; its own correction, made for seconds-long
        accelerations, took the roll the clip hid back in tens of seconds (decoupled 168 deg
        and VQF 118 deg off when the 3 s recovery ran out, then withheld). Re-seating is
        Fusion's recovery with its gain at the limit. Only near 1 g: the same pull about
        every axis in a pull-up's 2.4 g turned an attitude 60 deg off (``_after_dropped``)."""
        slow = rate[0] * rate[0] + rate[1] * rate[1] + rate[2] * rate[2] < _RESEAT_RATE_SQ
        if not (slow and self._reseat_pending) and \
                _tilt_pulled(self._q, g, 0.0)[1] <= RECOVERY_CHECKED_RAD:
            return
        # a reading taken in a fast rotation lags it (the chip's filters: decoupled 1.8 deg
        # off after the test's roll, 0.4 with the re-seat once slow); once the rotation has
        # slowed, one more re-seat from a reading that does not
        self._reseat_pending = not slow
        # the heading kept: NED north seen in the body, as a magnetometer would show it
        q = aligned_quaternion(g, to_local(self._q, (1.0, 0.0, 0.0)))
        if q is None:
            return
        self._reseat_tilt(q)
        self._q = q
        counts = self._counters["angular_rate_recovery"]
        counts["reseats"] = counts.get("reseats", 0) + 1

    def _reseat_tilt(self, q: Quat) -> None:
        """Hook for a filter whose kernel keeps the attitude: start the kernel's attitude
        again at ``q`` (body -> NED), its inclination filter anew (what it held was gravity
        through the attitude the clip corrupted), its gyro bias and magnetic reference
        kept."""
        raise NotImplementedError(f"{type(self).__name__} keeps no attitude of its own")

    def _process_general(self, item: Sample | Estimate) -> list[Estimate]:
        if isinstance(item, StreamGap):
            if item.stream == Quantity.GYRO:
                self._gap_at_ns = item.t_ns
                if self._dropped_after_ns is None:  # frames lost: unmeasured, as dropped ones
                    self._span_starts()
            return []
        if isinstance(item, VelocitySample):
            if item.valid and within_full_scale(item.velocity_ned_m_s, None):
                self._kinematics.on_velocity(item)
                self._no_speed = False
                self._nominal_only = False
            return []
        if isinstance(item, AirspeedSample):
            if item.valid and within_full_scale((item.airspeed_m_s,), None):
                self._kinematics.on_airspeed(item)
                self._no_speed = False
                self._nominal_only = False
            return []
        if not isinstance(item, (GyroSample, AccelSample, MagSample)):
            return []
        if not item.valid:
            if isinstance(item, GyroSample):
                return self._flagged_gyro(item)
            self._counters["invalid"][item.channel.value] += 1
            return []
        if not self._within_limits(item):
            return []
        if item.frame is not Frame.BODY_NED:
            return self._wrong_frame(item)
        if isinstance(item, AccelSample):
            self._accel_m_s2, self._accel_t_ns = _vec(item.accel_m_s2), item.t_ns
            return []
        if isinstance(item, MagSample):
            if self.uses_mag:
                self._mag_ut, self._mag_t_ns = _vec(item.mag_ut), item.t_ns
            return []
        rate = self._last_rate = _vec(item.gyro_rad_s)
        if self._start_watched or not self._tilt_aligned:
            return self._start_checked(item, rate)
        return self._measured_gyro(item, rate)

    def _measured_gyro(self, item: GyroSample, rate: Vec) -> list[Estimate]:
        """A valid gyro sample within the limits, body NED, with its ``rate`` (rad/s)."""
        if self._dropped_after_ns is not None:
            return self._after_dropped(item, rate)
        if self._recovery_left_s > 0.0:
            return self._recovering(item, rate)
        return self._on_gyro(item, rate)

    def moving_at_start(self, t_ns: int) -> None:
        """The pipeline's gyro start-up measurement gave up at ``t_ns``: the board moved at
        switch-on (a start in flight), so the attitude aligned on the next readings is
        checked (``start_check_s``). Forgotten at a reset."""
        del t_ns  # the very next readings align the filter (the pipeline calls it then)
        if not self._tilt_aligned:
            self._moving_at_start = True

    def _start_checked(self, item: GyroSample, rate: Vec) -> list[Estimate]:
        """A gyro step before the start is confirmed (``start_check_s``): the step runs as
        usual (aligning the filter at the first one with an accelerometer reading), and its
        estimate is withheld (UNSETTLED, counted ``start_check.withheld``) until the
        evidence holds: readings that can tell (fresh, turn-compensated, within
        START_CHECK_G of 1 g, turning slower than START_CHECK_RATE_RAD_S) agree with the
        attitude within START_CHECKED_RAD for ``start_check_s``, at least
        START_CHECK_SHARE of its steps, with no disagreeing one between them (each pulls
        the tilt towards it meanwhile: START_PULL_GAIN). Confirmed, the attitude stays
        watched: a reading that can tell and disagrees by more than START_LOST_RAD
        withholds again.

        Why (issue 26): switched on in flight, the filters aligned on a turn's specific
        force and handed out tilts 13-22 deg off as valid (seed-gps-vario, gy91; 82 deg on
        seed-rc-vario), and the vario behind them integrated the wrong tilt's gravity. One
        agreeing reading proves nothing (the alignment agrees with its own reading); a
        wrong attitude keeps agreeing with the readings only while the acceleration that
        fooled it stays constant in NED, which a turn's does not."""
        was_aligned = self._tilt_aligned
        out = self._measured_gyro(item, rate)
        if not self._start_watched or not out \
                or not self._start_withholds(was_aligned, item.t_ns, rate, self._step_accel):
            return out
        if not isinstance(out[0], AttitudeEstimate):
            return out  # already withheld, for its own reason
        return [RejectedEstimate(t_ns=item.t_ns, source=self.instance, kind="attitude",
                                 flags=EstimateFlag.UNSETTLED, estimator=self.name)]

    def _start_withholds(self, was_aligned: bool, t_ns: int, rate: Vec,
                         accel_m_s2: Vec | None) -> bool:
        """Whether the estimate of the step at ``t_ns`` (gyro ``rate``, rad/s, and its fresh
        accelerometer reading as measured, m/s^2 body, or None) is withheld by the start
        check, counted; the step that completes the evidence ends the check."""
        check = self._counters["start_check"]
        if not self._start_unchecked:
            # confirmed: watched, as its gyro offsets were not measured (START_LOST_RAD,
            # START_HOLD_S)
            g = self._telling_g(t_ns, rate, accel_m_s2)
            if g is None:
                if (t_ns - self._start_agreed_ns) * _NS <= START_HOLD_S:
                    return False
                check["expired"] = check.get("expired", 0) + 1
            elif _tilt_pulled(self._q, g, 0.0)[1] <= START_LOST_RAD:
                self._start_agreed_ns = t_ns
                return False
            else:
                check["lost"] = check.get("lost", 0) + 1
            self._start_unchecked = True
            self._start_since_ns = None
            self._start_readings = 0
        elif was_aligned and self._start_evidence(t_ns, rate, accel_m_s2):
            self._start_unchecked = False
            if check.get("confirmed_after_s") is None:
                check["confirmed_after_s"] = (t_ns - check.get("aligned_at_ns", t_ns)) * _NS
            return False
        check["withheld"] = check.get("withheld", 0) + 1
        return True

    def _telling_g(self, t_ns: int, rate: Vec, accel_m_s2: Vec | None) -> Vec | None:
        """The step's fresh accelerometer reading (m/s^2 body, as measured) less the turn's
        kinematic acceleration, as a gravity-positive reading (g), when it can tell the
        attitude at a start in motion: within START_CHECK_G of 1 g, at a rate under
        START_CHECK_RATE_RAD_S; else None."""
        if accel_m_s2 is None:
            return None
        if self._turn_on:
            kinematic = self._kinematics.acceleration(t_ns, rate)[1]
            if kinematic != NO_VECTOR:
                accel_m_s2 = compensated(accel_m_s2, kinematic)
        g = gravity_positive_g(accel_m_s2)
        if abs(math.sqrt(g[0] * g[0] + g[1] * g[1] + g[2] * g[2]) - 1.0) > START_CHECK_G:
            return None
        if rate[0] * rate[0] + rate[1] * rate[1] + rate[2] * rate[2] > _START_RATE_SQ:
            return None
        return g

    def _start_evidence(self, t_ns: int, rate: Vec, accel_m_s2: Vec | None) -> bool:
        """One step's evidence for the start check (``_start_checked``): True once it holds."""
        g = self._telling_g(t_ns, rate, accel_m_s2)
        if g is None:
            return False
        if self.owns_quaternion:
            dt = self._nominal_dt_s  # the estimate is withheld: the pull shapes the next
            self._q = _tilt_pulled(self._q, g, START_PULL_GAIN * dt)[0]
        if _tilt_pulled(self._q, g, 0.0)[1] > START_CHECKED_RAD:
            self._start_since_ns = None
            self._start_readings = 0
            return False
        if self._start_since_ns is None:
            self._start_since_ns = t_ns
        self._start_readings += 1
        self._start_agreed_ns = t_ns
        window = self.settings.start_check_s
        assert window is not None  # checked only when set (_align)
        return (t_ns - self._start_since_ns) * _NS >= window and \
            self._start_readings >= START_CHECK_SHARE * window / self._nominal_dt_s

    def _wrong_frame(self, item: GyroSample | AccelSample | MagSample) -> list[Estimate]:
        raise ValueError(
            f"{self.instance}: {type(item).__name__} from {item.device!r} is in the "
            f"{item.frame.value!r} frame; AHRS estimators take body NED samples (apply the "
            "mount first)"
        )

    def get_state(self) -> dict[str, Any]:
        return {
            "q": list(self._q),
            "last_gyro_t_ns": self._last_gyro_t_ns,
            "accel_m_s2": None if self._accel_m_s2 is None else list(self._accel_m_s2),
            "accel_t_ns": self._accel_t_ns,
            "mag_ut": None if self._mag_ut is None else list(self._mag_ut),
            "mag_t_ns": self._mag_t_ns,
            "counters": {**self._counters, "invalid": dict(self._counters["invalid"]),
                         "beyond_full_scale": dict(self._counters["beyond_full_scale"]),
                         "angular_rate_recovery": dict(
                             self._counters["angular_rate_recovery"]),
                         "start_check": dict(self._counters["start_check"])},
            "recovery_left_s": self._recovery_left_s,
            "reseat_pending": self._reseat_pending,
            "recovery_apart_rad": self._recovery_apart_rad,
            "last_rate_rad_s": list(self._last_rate),
            "dropped_after_ns": self._dropped_after_ns,
            "unchecked": self._unchecked,
            "step_accel_m_s2": None if self._step_accel is None else list(self._step_accel),
            "span_before": None if self._span_before is None
            else [list(self._span_before[0]), list(self._span_before[1]),
                  self._span_before[2]],
            "span_residual": None if self._span_residual is None
            else list(self._span_residual),
            "aligned": [self._tilt_aligned, self._heading_aligned],
            "start_check": [self._start_watched, self._start_unchecked, self._moving_at_start,
                            self._start_since_ns, self._start_readings,
                            self._start_agreed_ns],
            "kinematics": self._kinematics.as_dict(),
            "rest": list(self._rest),
            "at_rest": self._at_rest,
            "filter": self._filter_state(),
        }

    def set_state(self, state: dict[str, Any]) -> None:
        q = state["q"]
        self._q = (float(q[0]), float(q[1]), float(q[2]), float(q[3]))
        self._last_gyro_t_ns = state["last_gyro_t_ns"]
        self._accel_m_s2 = None if state["accel_m_s2"] is None else _vec(state["accel_m_s2"])
        self._accel_t_ns = state["accel_t_ns"]
        self._mag_ut = None if state["mag_ut"] is None else _vec(state["mag_ut"])
        self._mag_t_ns = state["mag_t_ns"]
        counters = state["counters"]
        self._counters = {**counters, "invalid": dict(counters["invalid"]),
                          "beyond_full_scale": dict(counters["beyond_full_scale"]),
                          "angular_rate_recovery": dict(counters.get(
                              "angular_rate_recovery",
                              {"clipped_samples": 0, "recoveries": 0, "withheld": 0}))}
        self._recovery_left_s = float(state.get("recovery_left_s", 0.0))
        self._reseat_pending = bool(state.get("reseat_pending", False))
        self._recovery_apart_rad = float(state.get("recovery_apart_rad", _INF))
        self._last_rate = _vec(state.get("last_rate_rad_s", NO_VECTOR))
        self._dropped_after_ns = state.get("dropped_after_ns")
        self._unchecked = bool(state.get("unchecked", False))
        step_accel = state.get("step_accel_m_s2")
        self._step_accel = None if step_accel is None else _vec(step_accel)
        span = state.get("span_before")
        self._span_before = None if span is None else (_vec(span[0]), _vec(span[1]),
                                                       int(span[2]))
        residual = state.get("span_residual")
        self._span_residual = None if residual is None else _vec(residual)
        self._tilt_aligned, self._heading_aligned = (bool(v) for v in state["aligned"])
        watched, unchecked, moving, since, readings, agreed = state.get(
            "start_check", (False, False, False, None, 0, 0))
        self._start_agreed_ns = int(agreed)
        self._start_watched, self._start_unchecked = bool(watched), bool(unchecked)
        self._moving_at_start = bool(moving)
        self._start_since_ns = None if since is None else int(since)
        self._start_readings = int(readings)
        self._counters["start_check"] = dict(counters.get(
            "start_check", {"withheld": 0, "confirmed_after_s": None}))
        self._kinematics.load_dict(state["kinematics"])
        self._no_speed = (self.settings.nominal_airspeed_m_s is None
                          and not self._kinematics.has_speed_source)
        self._nominal_only = (self._turn_on and self.settings.nominal_airspeed_m_s is not None
                              and not self._kinematics.has_speed_source)
        self._rest = tuple(float(v) for v in state.get("rest", REST_START))
        self._at_rest = bool(state.get("at_rest", False))
        self._set_filter_state(state["filter"])

    def diagnostics(self) -> dict[str, Any]:
        return {**self._counters, "invalid": dict(self._counters["invalid"]),
                "beyond_full_scale": dict(self._counters["beyond_full_scale"]),
                "angular_rate_recovery": {**self._counters["angular_rate_recovery"],
                                          "active": self._recovery_left_s > 0.0},
                "start_check": {**self._counters["start_check"],
                                "watched": self._start_watched,
                                "unconfirmed": self._start_unchecked},
                "turn_compensation": {**self._kinematics.counts,
                                      "source": self._kinematics.source},
                "rest": {"detection": self._rest_on, "at_rest": self._at_rest,
                         "rest_s": self._rest[8], "gyro_bias_rad_s": self.rest_gyro_bias_rad_s}}

    @property
    def rest_gyro_bias_rad_s(self) -> Vec:
        """The gyro bias learned at rest (rad/s, body; subtracted before each step; zeros
        before the first rest or without rest detection)."""
        r = self._rest
        return (r[9], r[10], r[11])

    def _rest_gyro(self, rate: Vec, accel_m_s2: Vec | None, dt: float) -> Vec:
        """One rest detector step for the gyro ``rate`` (rad/s, as measured) and the fused
        (turn-compensated) specific force (m/s^2; None: none), over ``dt`` (s): sets
        ``_at_rest`` and returns the rate less the bias learned at rest (the floats of the
        row loop, common/fast_ahrs.py)."""
        if accel_m_s2 is None:
            have_a, ax, ay, az = False, 0.0, 0.0, 0.0
        else:
            have_a = True
            ax, ay, az = accel_m_s2[0] * TO_G, accel_m_s2[1] * TO_G, accel_m_s2[2] * TO_G
        r, self._at_rest = rest_update(self._rest, self._rest_params, rate[0], rate[1],
                                       rate[2], have_a, ax, ay, az, dt)
        self._rest = r
        return (rate[0] - r[9], rate[1] - r[10], rate[2] - r[11])

    def _rest_arrays(self) -> tuple[FloatArray, FloatArray]:
        """The rest detector's state and parameters as a row kernel takes them (the state
        array is updated in place: :meth:`_kernel_finished` takes it back)."""
        return np.array(self._rest), np.array(self._rest_params)

    # ------------------------------------------------------------------ Python API
    @property
    def quaternion(self) -> FloatArray:
        """Current body -> NED quaternion (w, x, y, z)."""
        return np.array(self._q)

    def update(
        self,
        gyro_rad_s: Sequence[float],
        accel_m_s2: Sequence[float] | None = None,
        mag_ut: Sequence[float] | None = None,
        dt_s: float | None = None,
    ) -> FloatArray | None:
        """One step from plain vectors (body NED; rad/s, specific force m/s^2, uT).

        ``dt_s`` defaults to ``sample_period_s``. Returns the new quaternion, or None while the
        filter has no attitude yet (before the first accelerometer sample unless
        ``initial_attitude`` is ``identity``). Values beyond the full scales are not fused (a
        bad gyro returns None; a bad accelerometer is dropped). Only the nominal airspeed
        compensates turns here (velocity and airspeed need time stamps: use ``process``).
        """
        s = self.settings
        gyro = _vec(gyro_rad_s)
        if not within_full_scale(gyro, s.gyro_full_scale_rad_s):
            self._counters["beyond_full_scale"][Quantity.GYRO.value] += 1
            return None
        accel = None if accel_m_s2 is None else _vec(accel_m_s2)
        if accel is not None and not within_full_scale(accel, s.accel_full_scale_m_s2):
            self._counters["beyond_full_scale"][Quantity.ACCEL.value] += 1
            accel = None
        mag = _vec(mag_ut) if (mag_ut is not None and self.uses_mag) else None
        if mag is not None and not within_full_scale(mag, None):
            mag = None
        dt = s.sample_period_s if dt_s is None else float(dt_s)
        if self._run_step(None, gyro, accel, mag, dt) is None:
            return None
        return np.array(self._q)

    # ------------------------------------------------------------------ whole chunks
    # ------------------------------------------------------------------ blocks
    def update_block(self, block: Block) -> list[Estimate]:
        return self.update_blocks((block,))

    def update_blocks(self, blocks: Sequence[Block]) -> list[Estimate]:
        """The frames of one fusion step's blocks (see ``Estimator.update_blocks``): a gyro
        block, with or without an accelerometer and a magnetometer block, goes through the
        compiled row kernel in one call once the filter is aligned and its kernel covers
        its settings (``_block_kernel``), or through its compiled block step where it has
        one and the blocks are its case (``_block_step``); the frames before that
        (alignment, a filter's own set-up) go one by one. The estimates equal those of
        the frames one by one through ``process()`` to 1e-12 (bit for bit where
        ``process()`` runs the same compiled step, and through the block step;
        tests/filters/test_ahrs_blocks.py). Anything else (flagged or clipped
        frames, an angular-rate recovery under way, turn compensation by a speed) goes
        frame by frame."""
        return cast("list[Estimate]", self._update_blocks(blocks, as_block=False))

    def estimate_blocks(self, blocks: Sequence[Block]) -> list[Estimate | AttitudeBlock]:
        """``update_blocks``, with the frames the compiled block step takes as one
        :class:`AttitudeBlock` (its rows: the estimates ``update_blocks`` makes)."""
        return self._update_blocks(blocks, as_block=True)

    def _update_blocks(self, blocks: Sequence[Block], *, as_block: bool
                       ) -> list[Estimate | AttitudeBlock]:
        least = MIN_BLOCK_STEP_FRAMES if self._has_block_step() else \
            MIN_KERNEL_FRAMES if self._sample_kernel is None else \
            MIN_KERNEL_FRAMES_COMPILED_STEP
        if not any(b.kind is GyroSample and len(b) >= least for b in blocks):
            return list(Estimator.update_blocks(self, blocks))
        out: list[Estimate | AttitudeBlock] = []
        frames = _HEAD_FRAMES
        while blocks:
            streams = self._imu_streams(blocks)
            if streams is None:
                return out + Estimator.update_blocks(self, blocks)
            if self._ready(streams[2]):
                return out + self._kernel_blocks(*streams, as_block=as_block)
            # not aligned yet: a few frames one by one, then look again (twice as many
            # each time: a magnetometer that never gives a usable frame costs no more than
            # frame by frame)
            head, blocks = _head(blocks, streams[0], frames)
            out += Estimator.update_blocks(self, head)
            frames *= 2
        return out

    def attitude_rows(self, blocks: Sequence[Block]) -> AttitudeRows:
        """The estimates ``update_blocks`` makes of one fusion step's gyro, accelerometer
        and magnetometer blocks (valid, body NED: a log's chunk), as columns
        (:mod:`imuhal.estimation.rows`; the diagnostics flattened as the CSV writer
        flattens them): the same bookkeeping (``block_rows``), the rows before alignment
        in Python, the rest in the compiled kernel where the filter has one (else in
        Python too). The state carries on as it would frame by frame."""
        by_kind: dict[type, Block] = {}
        for b in blocks:
            if issubclass(b.kind, tuple(self.consumes)):
                if b.kind in by_kind:
                    raise ValueError(f"{self.instance}: two {b.kind.__name__} blocks in one "
                                     "step")
                by_kind[b.kind] = b
        gyro = by_kind.get(GyroSample)
        if gyro is None:
            raise ValueError(f"{self.instance}: attitude rows need a gyro block")
        steps = block_rows(self, gyro, by_kind.get(AccelSample), by_kind.get(MagSample))
        q, emitted, diagnostics = self._step_rows(steps, diagnostics=True)
        assert steps.t_ns is not None
        return AttitudeRows(self.instance, steps.t_ns[emitted], q[emitted], diagnostics)

    def _kernel_blocks(self, gyro: Block, accel: Block | None, mag: Block | None, *,
                       as_block: bool = False) -> list[Estimate | AttitudeBlock]:
        """The frames of the blocks through the compiled row kernel (``update_blocks``):
        in one compiled block step when the filter has one and the blocks are its common
        case (``_block_step``; ``as_block``: its estimates as one AttitudeBlock), else the
        bookkeeping on arrays around the row kernel."""
        done = self._block_step(gyro, accel, mag)
        if done is not None:
            q_rows, diag_rows, dt_rows, lin_rows = done
            if as_block:
                # the rows' diagnostics are made from these (fresh) arrays only when asked
                return [AttitudeBlock(self.instance, gyro.t_ns, q_rows, lin_rows, partial(
                    self._kernel_row_diagnostics, dt_rows, diag_rows,
                    self._kinematics.source))]
            build, instance = AttitudeEstimate.build, self.instance
            rows_diag = self._kernel_row_diagnostics(dt_rows, diag_rows,
                                                     self._kinematics.source)
            return [build(t, instance, (w, x, y, z), (lx, ly, lz), d)
                    for t, (w, x, y, z), (lx, ly, lz), d in zip(
                        gyro.t_ns.tolist(), q_rows.tolist(), lin_rows.tolist(), rows_diag,
                        strict=True)]
        return self._row_kernel_blocks(gyro, accel, mag)

    def _row_kernel_blocks(self, gyro: Block, accel: Block | None, mag: Block | None
                           ) -> list[Estimate | AttitudeBlock]:
        """``_kernel_blocks`` for blocks the block step does not take: ``block_rows``'s
        bookkeeping on arrays around the row kernel."""
        steps = block_rows(self, gyro, accel, mag)
        m = len(steps)
        if m == 0:
            return []
        q = np.empty((m, 4))
        diag = np.empty((m, self._kernel_diag_width))
        self._run_kernel(steps.gyro, self._fused_accel(steps.gyro, steps.accel), steps.mag,
                         steps.dts, q, diag)
        rows = self._kernel_row_diagnostics(steps.dts, diag, self._kinematics.source)
        build, instance = AttitudeEstimate.build, self.instance
        quats = [(w, x, y, z) for w, x, y, z in q.tolist()]
        assert steps.t_ns is not None  # block_rows always sets the times
        if m < _ROWS_LINEAR_FROM:
            # a few rows: the products on floats cost less than on arrays (the same floats)
            lin: list[Vec | None] = [
                None if a[0] != a[0] else _linear_accel_ned(qi, (a[0], a[1], a[2]))
                for qi, a in zip(quats, steps.accel.tolist(), strict=True)]
        else:
            has_a = (~np.isnan(steps.accel[:, 0])).tolist()
            lin = [(v[0], v[1], v[2]) if a else None for v, a in
                   zip(_linear_accel_ned_rows(q, steps.accel).tolist(), has_a, strict=True)]
        return [build(t, instance, qi, li, d)
                for t, qi, li, d in zip(steps.t_ns.tolist(), quats, lin, rows, strict=True)]

    def _block_step(self, gyro: Block, accel: Block | None, mag: Block | None
                    ) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray] | None:
        """An aligned filter's compiled block step (``_kernel_blocks``): every frame of the
        blocks stepped in one call, when they are ``block_rows``'s common case (every gyro
        frame steps, with an accepted accelerometer frame of its own instant, and a
        magnetometer frame likewise when one is kept), the estimator's held values,
        counters, turn and rest state left as the frames one by one leave them. Returns the
        quaternion after each step, the row kernel's diagnostics, the step lengths (s) and
        the gravity-compensated acceleration (NED, m/s^2); None, with nothing changed, for
        anything else or a filter without one (then ``block_rows`` and the row kernel)."""
        return None

    def _has_block_step(self) -> bool:
        """This filter has a compiled block step (``_block_step``) on this backend."""
        return False

    def _block_step_done(self, gyro: Block, accel: Block, mag: Block | None,
                         fallbacks: int) -> None:
        """The held values and counters a block step leaves (``block_rows``'s common case:
        the last gyro, accelerometer and kept magnetometer frame are held)."""
        t_last = int(gyro.t_ns[-1])
        gx, gy, gz = gyro.values[-1].tolist()
        self._last_gyro_t_ns = t_last
        self._last_rate = (gx, gy, gz)
        ax, ay, az = accel.values[-1].tolist()
        self._accel_m_s2 = (ax, ay, az)
        self._accel_t_ns = t_last
        # the accelerometer frame the last step had: process() keeps it for a span of
        # unfused frames after the block (_span_starts), as the frames one by one would
        self._step_accel = self._accel_m_s2
        if mag is not None and self.uses_mag:
            mx, my, mz = mag.values[-1].tolist()
            self._mag_ut = (mx, my, mz)
            self._mag_t_ns = t_last
        self._counters["dt_fallbacks"] += fallbacks

    def _imu_streams(self, blocks: Sequence[Block]
                     ) -> tuple[Block, Block | None, Block | None] | None:
        """The gyro, accelerometer and magnetometer block of a fusion step the compiled row
        kernel can take at once once aligned, or None (then frame by frame; see
        ``update_blocks``)."""
        by_kind: dict[type, Block] = {}
        for b in blocks:
            if b.kind not in (GyroSample, AccelSample, MagSample) or b.kind in by_kind \
                    or b.frame is not _BODY_NED or b.flagged:
                return None
            by_kind[b.kind] = b
        gyro = by_kind.get(GyroSample)
        if gyro is None or not self._block_kernel() or self._recovery_left_s > 0.0 \
                or self._dropped_after_ns is not None or self._start_watched \
                or not self._kernel_allowed():
            return None
        return gyro, by_kind.get(AccelSample), by_kind.get(MagSample)

    def _ready(self, mag: Block | None) -> bool:
        """Aligned and set up: nothing but the kernel's steps is left to happen."""
        if not (self._tilt_aligned and self._kernel_ready()):
            return False
        # else the heading is still to be set from a magnetometer frame
        return self._heading_aligned or (mag is None and self._mag_ut is None)

    def _block_kernel(self) -> bool:
        """This filter's compiled row kernel covers its settings and
        ``_kernel_row_diagnostics`` gives its per-step diagnostics (False: blocks go frame
        by frame)."""
        return False

    def _kernel_row_diagnostics(self, dts: FloatArray, diag: FloatArray, source: str
                                ) -> list[dict[str, Any]]:
        """Each kernel step's diagnostics dictionary, as ``process()`` makes it: ``dt_s``,
        ``turn_compensation`` (``source``), then the filter's (from ``diag``, the row
        kernel's array). Only filters whose ``_block_kernel`` is True define it."""
        raise NotImplementedError

    def _step_rows(self, steps: StepRows, *, diagnostics: bool, out: FloatArray | None = None
                   ) -> tuple[FloatArray, np.ndarray, dict[str, DiagnosticColumn]]:
        """One filter step per row of ``steps``: the quaternion after each (NaN where there
        was no attitude yet; written into ``out`` when given, NaN-filled), which rows made
        an estimate, and the diagnostics columns of those rows (when asked). Rows run in
        Python until nothing is left to align, the rest in the compiled kernel when there
        is one (else in Python too)."""
        m = len(steps)
        if out is None:
            out = np.full((m, 4), np.nan)
        emitted = np.zeros(m, dtype=bool)
        has_mag = ~np.isnan(steps.mag[:, 0])
        mag_left = np.logical_or.accumulate(has_mag[::-1])[::-1]
        py_diags: list[dict[str, Any]] = []
        stop = 0
        if self._kernel_allowed():
            while stop < m and not (self._tilt_aligned and self._kernel_ready()
                                    and not self._start_watched
                                    and (self._heading_aligned or not mag_left[stop])):
                py_diags += self._python_rows(steps, stop + 1, out, emitted, diagnostics, stop)
                stop += 1
        else:
            py_diags = self._python_rows(steps, m, out, emitted, diagnostics)
            stop = m
        kernel_diag: dict[str, DiagnosticColumn] = {}
        in_kernel = 0
        if stop < m:
            rest = slice(stop, m)
            # without diagnostics the kernel writes every row's into one scratch row
            diag = np.empty((m - stop if diagnostics else 1, self._kernel_diag_width))
            gyro = steps.gyro[rest]
            if self._run_kernel(gyro, self._fused_accel(gyro, steps.accel[rest]),
                                steps.mag[rest], steps.dts[rest], out[rest], diag):
                emitted[rest] = True
                in_kernel = m - stop
                if diagnostics:
                    kernel_diag = {"dt_s": steps.dts[rest], **self._kernel_diagnostics(diag)}
            else:
                py_diags += self._python_rows(steps, m, out, emitted, diagnostics, stop)
        return out, emitted, merge_columns(py_diags, kernel_diag, in_kernel)

    def _python_rows(self, steps: StepRows, stop: int, out: FloatArray, emitted: np.ndarray,
                     diagnostics: bool, start: int = 0) -> list[dict[str, Any]]:
        """Rows ``start:stop`` of ``steps`` through the Python step (the reference path)."""
        rows = slice(start, stop)
        gyro = steps.gyro[rows].tolist()
        accel = steps.accel[rows].tolist()
        mag = steps.mag[rows].tolist()
        dts = steps.dts[rows].tolist()
        t_ns = [None] * (stop - start) if steps.t_ns is None else steps.t_ns[rows].tolist()
        diags: list[dict[str, Any]] = []
        run, kin = self._run_step, self._kinematics
        for i, g, a, mg, dt, t in zip(range(start, stop), gyro, accel, mag, dts, t_ns,
                                      strict=True):
            was_aligned = self._tilt_aligned
            accel_i = None if a[0] != a[0] else (a[0], a[1], a[2])
            diag = run(t, (g[0], g[1], g[2]), accel_i,
                       None if mg[0] != mg[0] else (mg[0], mg[1], mg[2]), dt)
            if diag is None:
                continue
            if self._start_watched and t is not None and self._start_withholds(
                    was_aligned, t, (g[0], g[1], g[2]), accel_i):
                continue  # a row the start check withholds: no estimate (counted)
            out[i] = self._q
            emitted[i] = True
            if diagnostics:
                diags.append(flatten_diagnostics({"dt_s": dt, "turn_compensation": kin.source,
                                                  **diag}))
        return diags

    # ------------------------------------------------------------------ compiled kernels
    _compiled_kernel: ClassVar[fast.Kernel | None] = None
    """The estimator's compiled kernel (None: it has none; its rows run in Python)."""
    _kernel_diag_width: ClassVar[int] = 0
    """Columns of the per-row diagnostics array the compiled kernel fills."""

    def _run_kernel(self, gyro: FloatArray, accel: FloatArray, mag: FloatArray,
                    dts: FloatArray, out: FloatArray, diag: FloatArray) -> bool:
        """Step every (resolved, aligned) row in the compiled kernel, writing the quaternion
        after each into ``out`` and its diagnostics into ``diag``, then take over its state
        (:meth:`_kernel_finished`); False, with nothing done, when this estimator has no
        kernel for its settings. A NaN row of ``accel``/``mag``: none this step."""
        return False

    _sample_kernel: Any = None
    """The compiled per-sample step (:meth:`fast.Kernel.per_sample`, set by a filter's
    ``_reset_filter``), or None: ``_step`` runs in Python."""

    _linear_ned: Vec | None = None
    """The gravity-compensated acceleration (NED, m/s^2) the last compiled step returned."""

    def _compiled_step(self, gyro: Vec, accel_m_s2: Vec | None, mag: Vec | None, dt: float,
                       measured_m_s2: Vec | None) -> dict[str, Any] | None:
        """``_step`` through ``_sample_kernel`` (accelerometer as specific force, m/s^2, turn
        compensated): the same quaternion, and the estimate's whole diagnostics dictionary
        (``dt_s`` and ``turn_compensation`` first, then what ``_step`` returns, one dictionary
        built where the Python path merges two); it also leaves in ``_linear_ned``
        the gravity-compensated acceleration of ``measured_m_s2`` (the specific force before
        turn compensation) at the new attitude, as ``_linear_accel_ned`` computes it. Only
        filters that set a kernel define it."""
        raise NotImplementedError

    def _kernel_ready(self) -> bool:
        """Nothing but the kernel's step is left to happen (a filter's own set-up is done)."""
        return True

    def _kernel_diagnostics(self, diag: FloatArray) -> dict[str, DiagnosticColumn]:
        """The kernel's ``diag`` array as the columns ``_step``'s dictionary flattens to."""
        return {}

    def _kernel_allowed(self) -> bool:
        """The compiled kernels cover turn compensation by the nominal airspeed (the
        accelerometer rows they fuse are compensated beforehand, ``_fused_accel``), not by
        a velocity or airspeed source (their fits and filters stay frame by frame)."""
        return self._rows_kernel() is not None and not (
            self.settings.turn_compensation and self._kinematics.has_speed_source)

    _rows_call: Any = None
    _rows_chosen: bool = False

    def _rows_kernel(self) -> Any:
        """This filter's compiled row kernel (``_compiled_kernel.unchecked()``: the row
        arrays are built by ``common/rows.py``, the scalars from the settings), or None
        where it has none or it runs in Python. Chosen at the first use after ``reset``
        (as the per-sample step is at ``reset``), so that a run that never takes the row
        path loads no compiled kernel, and a fusion step's call pays no backend look-up."""
        if not self._rows_chosen:
            kernel = self._compiled_kernel
            self._rows_call = kernel.unchecked() if kernel is not None and \
                kernel.available() else None
            self._rows_chosen = True
        return self._rows_call

    def _fused_accel(self, gyro: FloatArray, accel: FloatArray) -> FloatArray:
        """The accelerometer rows a row kernel fuses with the ``gyro`` rows (specific force,
        m/s^2, body; NaN: none): less the nominal airspeed's kinematic acceleration when
        turns are compensated by it (``turn.nominal_rows``: the floats of ``_run_step``),
        else as they are. The estimates' gravity-compensated acceleration is still taken
        from the rows as measured."""
        s = self.settings
        speed = s.nominal_airspeed_m_s
        if speed is None or not s.turn_compensation:
            return accel
        return nominal_rows(accel, gyro, float(speed))

    def _kernel_finished(self, q: FloatArray, steps: int, closed: int, turn_sum: float,
                         rest: FloatArray | None = None) -> None:
        """Take over what a kernel left: the quaternion, counters, turn bookkeeping and
        (``rest``, from :meth:`_rest_arrays`) the rest detector's state."""
        if rest is not None:
            self._rest = tuple(rest.tolist())
            # at rest after a step exactly when the still time reached the rest time
            self._at_rest = self._rest_on and self._rest[7] >= self._rest_params[4]
        w, x, y, z = q.tolist()
        self._q = (w, x, y, z)
        self._kinematics.add_turn_steps(float(turn_sum), steps)
        self._counters["steps"] += steps
        if "gate_closed_steps" in self._counters:
            self._counters["gate_closed_steps"] += int(closed)

    # ------------------------------------------------------------------ internals
    def _within_limits(self, item: GyroSample | AccelSample | MagSample) -> bool:
        """False (and counted) for a value no sensor can report: beyond full scale, NaN, inf."""
        s = self.settings
        if isinstance(item, GyroSample):
            ok = within_full_scale(item.gyro_rad_s, s.gyro_full_scale_rad_s)
        elif isinstance(item, AccelSample):
            ok = within_full_scale(item.accel_m_s2, s.accel_full_scale_m_s2)
        else:
            ok = within_full_scale(item.mag_ut, None)
        if not ok:
            self._reject(item.channel.value)
        return ok

    def _reject(self, channel: str) -> None:
        """Count a value beyond the full scale (or not finite) on ``channel``."""
        self._counters["beyond_full_scale"].setdefault(channel, 0)
        self._counters["beyond_full_scale"][channel] += 1

    def _align(self, accel: Vec | None, mag: Vec | None) -> bool:
        """Set the attitude from the first accel (and mag) sample; True once tilt is set."""
        if accel is None:
            return self._tilt_aligned
        if not self._tilt_aligned or (not self._heading_aligned and mag is not None):
            q = aligned_quaternion(gravity_positive_g(accel), mag)
            if q is None:
                return self._tilt_aligned
            self._q = q
            self._tilt_aligned = True
            self._heading_aligned = self._heading_aligned or mag is not None
            self._on_aligned()
        return True

    def _on_aligned(self) -> None:
        """Hook: the attitude was just set from the sensors (filters may reset internals)."""

    def _run_step(self, t_ns: int | None, gyro: Vec, accel: Vec | None, mag: Vec | None,
                  dt: float) -> dict[str, Any] | None:
        """Compensate, align if needed, and run one kernel step; None: no estimate yet."""
        kin = self._kinematics.step(t_ns, gyro)
        measured = accel
        if accel is not None and kin != NO_VECTOR:
            accel = compensated(accel, kin)
        # once aligned (the heading too, or no mag this step) _align has nothing to do
        if not (self._tilt_aligned and (self._heading_aligned or mag is None)):
            was_aligned = self._tilt_aligned
            if not self._align(accel, mag):
                return None
            if not was_aligned and t_ns is not None and self._moving_at_start \
                    and self.settings.start_check_s is not None:
                # the first alignment, from the sensors, on time-stamped samples (``update``
                # has none): checked from here on (_start_checked)
                self._start_watched = self._start_unchecked = True
                self._start_since_ns = None
                self._start_readings = 0
                self._counters["start_check"]["aligned_at_ns"] = t_ns
        self._counters["steps"] += 1
        if self._rest_on:
            gyro = self._rest_gyro(gyro, accel, dt)
        if self._sample_kernel is not None:
            return self._compiled_step(gyro, accel, mag, dt, measured)
        accel_g = None if accel is None else gravity_positive_g(accel)
        return self._step(ImuStep(gyro, accel_g, mag, dt))

    def _on_gyro(self, gyro: GyroSample, rate: Vec) -> list[Estimate]:
        # _dt_for and _fresh written out: this runs once per gyro sample
        t_ns = gyro.t_ns
        last = self._last_gyro_t_ns
        dt = self._nominal_dt_s
        if self._dt_from_timestamps and last is not None:
            step_s = (t_ns - last) * _NS
            dt = step_s if 0.0 < step_s <= self._max_dt_s else self._unusual_step(t_ns, step_s)
        self._last_gyro_t_ns = t_ns
        max_age = self._max_aux_age_s
        accel = self._accel_m_s2
        if accel is not None:
            a_t = self._accel_t_ns
            if a_t is None:
                accel = None
            elif max_age is not None and (t_ns - a_t) * _NS > max_age:
                self._counters["stale_accel"] += 1
                accel = None
        self._step_accel = accel
        mag = self._mag_ut
        if mag is not None:
            m_t = self._mag_t_ns
            if m_t is None:
                mag = None
            elif max_age is not None and (t_ns - m_t) * _NS > max_age:
                self._counters["stale_mag"] += 1
                mag = None
        if (self._no_speed or self._nominal_only) and self._sample_kernel is not None and \
                self._tilt_aligned and (self._heading_aligned or mag is None):
            # the common compiled cases written out (aligned: nothing to align; no speed
            # source, or the nominal airspeed alone): what _run_step does, without its calls
            fused = self._simple_kinematics(rate, accel)
            self._counters["steps"] += 1
            corrected = self._rest_gyro(rate, fused, dt) if self._rest_on else rate
            diag = self._compiled_step(corrected, fused, mag, dt, accel)
            return [AttitudeEstimate.build(t_ns, self.instance, self._q,
                                           None if accel is None else self._linear_ned, diag)]  # type: ignore[arg-type]  # aligned (checked above): a kernel step then always returns diagnostics
        return self._stepped(t_ns, rate, accel, mag, dt)

    def _simple_kinematics(self, rate: Vec, accel: Vec | None) -> Vec | None:
        """``KinematicAcceleration.step`` and ``_run_step``'s compensation for the two cases
        ``_on_gyro`` writes out, on floats: with no speed source only the turn bookkeeping
        (the specific force as it is); by the nominal airspeed V, the force less
        ``(0, r V, -q V)`` (``turn._along_x``) unless that is zero, as ``_run_step`` leaves
        it. Returns the specific force to fuse (m/s^2, body)."""
        kin = self._kinematics
        if not self._turn_on:
            kin.source = "off"
            return accel
        kin.count_turn(rate)
        if self._no_speed:
            return accel
        kin.source = "nominal"
        kin.counts["compensated_steps"] += 1
        if accel is None:
            return None
        speed = self.settings.nominal_airspeed_m_s
        ky, kz = rate[2] * speed, -rate[1] * speed  # type: ignore[operator]  # _nominal_only: set
        if ky == 0.0 and kz == 0.0:
            return accel
        return (accel[0] - 0.0, accel[1] - ky, accel[2] - kz)

    def _unusual_step(self, t_ns: int, step_s: float) -> float:
        """The step length for a gyro step not in (0, ``max_dt_s``]: its true interval when
        the pipeline counted the frames lost in it (a StreamGap for this frame) and it is
        at most ``max_gap_s``; else the nominal period (a time stamp that jumped, went back
        or repeated), counted."""
        if t_ns == self._gap_at_ns and 0.0 < step_s <= self._max_gap_s:
            return step_s
        self._counters["dt_fallbacks"] += 1
        return self._nominal_dt_s

    def _stepped(self, t_ns: int, rate: Vec, accel: Vec | None, mag: Vec | None,
                 dt: float) -> list[Estimate]:
        """The estimate of one step through ``_run_step`` (compensation, alignment, the
        compiled or the Python step): ``_on_gyro`` for every case but the common compiled
        one it writes out; none before the attitude is aligned."""
        diag = self._run_step(t_ns, rate, accel, mag, dt)
        if diag is None:
            return []
        if self._sample_kernel is not None:
            # the compiled step left the acceleration and built the whole dictionary
            return [AttitudeEstimate.build(t_ns, self.instance, self._q,
                                           None if accel is None else self._linear_ned, diag)]
        return [
            AttitudeEstimate.build(
                t_ns,
                self.instance,
                self._q,
                None if accel is None else _linear_accel_ned(self._q, accel),
                {"dt_s": dt, "turn_compensation": self._kinematics.source, **diag},
            )
        ]
