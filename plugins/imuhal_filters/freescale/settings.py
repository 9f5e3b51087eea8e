"""Settings of the Freescale Kalman filters: timing, coordinate system and fusion.h tuning.

Units are the reference's own, because the tuning constants are variances in those units:
g (accelerometer), uT (magnetometer), deg/s (gyro), degrees (orientation error). Each field
names the fusion.h / build.h constant it stands for; defaults are those of build 422.
"""

from __future__ import annotations

from typing import Any, ClassVar

from pydantic import Field

from imuhal_filters.common.ahrs import AhrsLimitSettings
from imuhal_filters.common.presets import PresetSettings
from imuhal_filters.common.rest import RestSettings
from imuhal_filters.common.turn import TurnCompensationSettings
from imuhal_filters.freescale.coords import CoordinateSystem

_REFERENCE: dict[str, Any] = {"initialise_on_first_step": True, "turn_compensation": False,
                              "accel_soft_gate_g": None, "accel_innovation_gate_sigma": None,
                              "accel_mag_input": "latest", "rest_detection": False,
                              "qw_init_offset_dps2": 250e-3}
"""Build 422 as published (the values the conformance tests run)."""
_REFERENCE_9DOF: dict[str, Any] = {**_REFERENCE, "max_inclination_deg": 65.0,
                                   "lock_sets_inclination": False,
                                   "mag_max_accel_distrust": None,
                                   "mag_innovation_gate_sigma": None}


TURN_ON_OFFSET_SIGMA_DPS = 5.0 / 3.0
"""One standard deviation (deg/s) of a bundled gyro's turn-on zero-rate offset: the MPU-9250's
specified +-5 deg/s (the largest of the bundled gyros, the bound ``rest_first_max_rate_deg_s``
also takes) read as three standard deviations."""


class FreescaleCommonSettings(PresetSettings, AhrsLimitSettings, TurnCompensationSettings,
                              RestSettings):
    """What the 6DOF and 9DOF filters share.

    Rest detection (``common/rest.py``, the detector madgwick, mahony and imufilter use) is
    on by default: at rest the accelerometer is fused without the soft and innovation gates,
    and the window's mean gyro reading, which is then the gyro offset alone, is fused as a
    measurement of the offset state (``kalman.FreescaleKalman.step``).

    Defaults differ from build 422 where a measurement showed the reference's value costs
    accuracy (docs/estimators.md); ``preset: reference`` (or ``seed``) restores build 422.
    """

    PRESETS: ClassVar[dict[str, dict[str, Any]]] = {"reference": _REFERENCE, "seed": _REFERENCE}

    sensor_rate_hz: float = Field(default=200.0, gt=0.0)
    """SENSORFS: the rate of the gyro samples; each is integrated over 1 / sensor_rate_hz."""
    oversample_ratio: int = Field(default=8, ge=1, le=64)
    """OVERSAMPLE_RATIO: gyro samples per Kalman step (200 Hz / 8 = 25 Hz Kalman)."""
    max_gap_s: float = Field(default=1.0, gt=0.0)
    """Gyro frames the pipeline counted lost (a StreamGap before the frame after them,
    imuhal.core.gaps) are integrated at the rate of that frame, one fast tick each, when the
    loss spans at most this long; a longer loss restarts the filter (it locks again to the
    accelerometer, and the magnetometer on 9DOF). A step no counted loss explains is one
    tick, as every step is in the reference."""
    coordinate_system: CoordinateSystem = CoordinateSystem.NED
    """THISCOORDSYSTEM: which of the reference's three builds runs (``ned``, ``android``,
    ``win8``; the core conventions aerospace, android, win8). Each has its own sensor model,
    eCompass/tilt lock and inclination update, and reproduces the reference compiled for that
    system; estimators still take body-NED samples and emit body -> NED quaternions. The
    9DOF builds agree within float round-off; the Android 6DOF tilt lock picks a heading a
    fraction of a degree apart (docs/units-and-frames.md)."""
    accel_mag_input: str = Field(default="average", pattern="^(latest|average)$")
    """What the Kalman step measures: ``latest`` is the reference (the newest fast accel and
    mag sample, "to reduce phase errors"); ``average`` (default) uses the mean of the
    decimation window: less noise, and a loop's or a pull-up's peaks are averaged rather than
    sampled (``rc-flight`` tilt max 8 against 12-19 deg, docs/estimators.md)."""
    initialise_on_first_step: bool = False
    """Reference start-up (True): the first Kalman step only initialises (no estimate); the
    second locks to the accelerometer tilt (6DOF) or eCompass (9DOF) and fuses. Default: the
    first Kalman step locks (the alignment every imuhal AHRS does on its first sample)."""

    accel_soft_gate_g: float | None = Field(default=0.02, gt=0.0)
    """Trust the accelerometer less as its (turn-compensated) magnitude departs from 1 g:
    its noise variance is multiplied by (1 + (| |a| - 1 | / this)^2)^2. None: build 422,
    which loses the attitude in ``rc-flight``'s loop (docs/estimators.md)."""
    accel_innovation_gate_sigma: float | None = Field(default=3.0, gt=0.0)
    """Trust the accelerometer less when its gravity innovation is implausible: beyond this
    many standard deviations (Mahalanobis distance m of the 3-element gravity error against
    its innovation covariance) its noise variance is multiplied by (m / this)^4. It catches
    what the soft gate cannot: a sustained acceleration across gravity, which hardly changes
    |a| but would tilt the attitude and corrupt the gyro offset estimate (``thermal`` with
    GNSS velocity: 1.41 -> 0.80 deg tilt RMS, docs/estimators.md). None: build 422."""
    accel_gate_reacquire_s: float = Field(default=2.0, gt=0.0)
    """The innovation gate closed this long (s) without a break means the attitude, not the
    accelerometer, is wrong (a gyro glitch): fuse at full weight until it opens again."""
    qv_accel_g2: float = Field(default=2e-6, gt=0.0)
    """FQVA: accelerometer noise variance (g^2)."""
    qv_gyro_dps2: float = Field(default=0.3, gt=0.0)
    """FQVG: gyro noise variance ((deg/s)^2)."""
    qw_gyro_offset_dps2: float = Field(default=1e-9, ge=0.0)
    """FQWB: gyro offset random-walk variance per step ((deg/s)^2)."""
    qw_accel_g2: float = Field(default=1e-4, gt=0.0)
    """FQWA: linear acceleration drift variance (g^2)."""
    qw_init_theta_deg2: float = Field(default=2000e-5, ge=0.0)
    """FQWINITTHTH: initial orientation error variance (deg^2)."""
    qw_init_offset_dps2: float = Field(default=TURN_ON_OFFSET_SIGMA_DPS**2, ge=0.0)
    """FQWINITBB: initial gyro offset error variance ((deg/s)^2). Default (5/3)^2 = 2.78: a
    gyro whose turn-on offset nobody measured (``TURN_ON_OFFSET_SIGMA_DPS``). Build 422's
    0.25 (0.5 deg/s) trusts the start so much that a still board with 4, -3, 2 deg/s of
    uncorrected offset is 7.5 deg off after 1-10 s (1.2 deg with 2.78, before rest
    detection; tests/filters/test_freescale_rest.py)."""
    qw_init_theta_offset: float = 0.0
    """FQWINITTHB: initial orientation / gyro offset covariance (deg^2/s)."""
    qw_init_accel_g2: float = Field(default=10e-5, ge=0.0)
    """FQWINITAA: initial linear acceleration error variance (g^2)."""
    accel_decay: float = Field(default=0.5, ge=0.0, le=1.0)
    """FCA: per-step decay of the linear acceleration estimate (Markov process)."""

    @property
    def fast_dt_s(self) -> float:
        return 1.0 / self.sensor_rate_hz

    @property
    def kalman_dt_s(self) -> float:
        return self.oversample_ratio / self.sensor_rate_hz


class Freescale6DofSettings(FreescaleCommonSettings):
    """COMPUTE_6DOF_GY_KALMAN: accelerometer + gyro, 9-element error vector."""

    PRESETS: ClassVar[dict[str, dict[str, Any]]] = {"reference": _REFERENCE, "seed": _REFERENCE}


class Freescale9DofSettings(FreescaleCommonSettings):
    """COMPUTE_9DOF_GBY_KALMAN: accelerometer + magnetometer + gyro, 12-element error vector.

    The magnetometer must already be calibrated (hard and soft iron removed): the reference
    here runs with its calibration forced valid (offset 0, inverse soft iron identity) and
    ``field_strength_ut`` as the fitted field B.
    """

    PRESETS: ClassVar[dict[str, dict[str, Any]]] = {"reference": _REFERENCE_9DOF,
                                                    "seed": _REFERENCE_9DOF}

    qv_mag_ut2: float = Field(default=0.1, gt=0.0)
    """FQVM: magnetometer noise variance (uT^2)."""
    qw_mag_disturbance_ut2: float = Field(default=0.5, gt=0.0)
    """FQWD: magnetic disturbance drift variance (uT^2)."""
    qw_init_disturbance_ut2: float = Field(default=600e-3, ge=0.0)
    """FQWINITDD: initial magnetic disturbance error variance (uT^2)."""
    disturbance_decay: float = Field(default=0.5, ge=0.0, le=1.0)
    """FCD: per-step decay of the magnetic disturbance estimate."""
    max_inclination_deg: float = Field(default=88.0, gt=0.0, le=90.0)
    """SINDELTAMAX / COSDELTAMAX: the tracked geomagnetic inclination is clamped to +-this.
    Build 422 clamps at 65 deg, which biases the tilt wherever the dip is larger (most of
    Europe and North America: BROAD trial 02, 2.30 deg inclination error at 65 against 0.50
    at 80); 88 deg covers every inhabited place (docs/estimators.md)."""
    lock_sets_inclination: bool = True
    """When the filter locks to the eCompass, also point the reference geomagnetic vector at
    the measured inclination (build 422 keeps it horizontal and lets tracking find the dip,
    which leaves the attitude about 1.5 deg off for the first seconds)."""
    field_strength_ut: float = Field(default=50.0, gt=0.0)
    """B (uT): DEFAULTB and the magnetic calibration's fitted field. Sets the reference
    geomagnetic vector's length, the jamming threshold |d|^2 > (2 B)^2 and the
    magnetometer term of the measurement noise."""
    mag_max_accel_distrust: float | None = Field(default=10.0, ge=1.0)
    """While the soft and innovation gates multiply the accelerometer noise by more than
    this, the magnetometer corrects only its disturbance estimate, not the orientation or
    the gyro offset: alone it would steer the tilt (uncalibrated board in `rc-flight`:
    68 -> 4.3 deg tilt RMS; BROAD trial 07, fast rotation: 99 -> 6.8 deg total). None:
    always (build 422)."""
    mag_innovation_gate_sigma: float | None = Field(default=5.0, gt=0.0)
    """The magnetometer corrects the orientation and the gyro offset only while its
    innovation's Mahalanobis distance (against the magnetometer block of the innovation
    covariance; the innovation against the predicted field at the field length the lock
    measured, not at ``field_strength_ut``) is within this many standard deviations; beyond
    it, as with a gated accelerometer, the gyro carries the attitude and the tracked
    inclination stays. 5 sigma: a 3-axis Gaussian innovation
    exceeds it about once in 70,000 steps. An uncalibrated magnetometer's hard iron, turning
    with the board, fails it in turns (uncalibrated seed board, `thermal` with the nominal
    airspeed: tilt max 55 -> 6.0 deg). None: always (build 422)."""
    mag_gate_reacquire_s: float | None = Field(default=3.0, gt=0.0)
    """The magnetometer gate rejecting this long (s) without a break innovations that one
    and the same heading offset explains (the field seen through the attitude is the
    reference field turned about the vertical, its length and dip as expected) means the
    heading, not the field, is wrong: the heading is turned by that offset and the
    magnetometer steers again (``kalman.FreescaleKalman._mag_gate_verdict``). Longer than
    a passing disturbance (2 s of a field turned 60 deg stays rejected). None: the gate
    never reacquires."""
    full_innovation_inverse: bool = False
    """Build 422 inverts only the top-left 3x3 block of the 6x6 innovation covariance
    (``fmatrixAeqInvA(..., 3)``) and uses the other blocks uninverted; False reproduces that.
    True inverts the whole 6x6 matrix (the textbook Kalman gain; not the reference)."""
