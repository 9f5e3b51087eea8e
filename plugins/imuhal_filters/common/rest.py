"""Rest detection: the board lying still, the one moment an AHRS knows its inputs exactly.

At rest the gyro measures nothing but its own bias and the accelerometer nothing but
gravity. The complementary filters' soft gate (common/gate.py) fades the accelerometer as the
reading departs from the gravity the attitude predicts; an uncorrected gyro bias then drifts
the attitude, the departure grows, the correction fades further, and the filter can settle
far from the truth even on a bench (mahony, `magnet` as delivered: 26.9 deg tilt RMS before
this module, docs/estimators.md). Knowing the board is still ends that loop twice over:

1. the accelerometer is trusted fully (the soft gate's weight is 1), since it reads gravity;
2. the gyro bias is learned from the still gyro (a first-order average with time constant
   ``rest_bias_tau_s``, started from the low-passed rate at the first rest), and subtracted
   from every gyro sample the filter integrates from then on, at rest or not.

The rule (after VQF's rest detection, Laidig and Seel 2023, in its own terms): both sensors
are low-passed (first order, time constant ``rest_filter_tau_s``); the board is still at a
step when the gyro reading is within ``rest_gyro_deviation_deg_s`` of its low-passed value,
the accelerometer within ``rest_accel_deviation_g`` of its own, and the low-passed rate,
less the bias learned so far, within ``rest_max_rate_deg_s`` on every axis (before any
bias was learned, within ``rest_first_max_rate_deg_s``: the largest turn-on offset of the
bundled gyros); it is at rest once it has been still for ``rest_min_s`` without a break.
A step without an accelerometer reading breaks the stillness (nothing says it reads
gravity). Slow steady motion can pass for rest: a turn slower than the rate bound (a
paraglider's 1 deg/s turn at 10 m/s pulls 0.018 g sideways, 1 deg of tilt) or a straight,
unaccelerated glide, where the reading is gravity anyway.

The state is a tuple of floats (:data:`REST_STATE_SIZE`, see
:func:`~imuhal_filters.common.fast_ahrs.rest_update`) carried by the estimator between
steps and through the compiled row kernels' calls, so blocks and frames one by one give the
same floats; the settings go to the kernels as :func:`rest_params`.
"""

from __future__ import annotations

import math

from pydantic import Field

from imuhal.estimation.base import EstimatorSettings

REST_STATE_SIZE = 12
"""Floats in a rest detector's state: started, low-passed gyro (3, rad/s), low-passed
accelerometer (3, g), still time (s), time at rest so far (s), learned gyro bias (3, rad/s)."""
REST_BIAS = slice(9, 12)
"""Where the learned gyro bias (rad/s, body) sits in the state."""
REST_OFF: tuple[float, ...] = (0.0,) * 8
"""The parameters of a detector that is off (never at rest, never learns a bias)."""
_DEG = math.pi / 180.0


class RestSettings(EstimatorSettings):
    """Rest detection (``imuhal_filters.common.rest``). Thresholds in physical units."""

    rest_detection: bool = True
    """Detect rest; at rest trust the accelerometer fully and learn the gyro bias, which is
    then subtracted from every gyro sample. False: the references' behaviour."""
    rest_filter_tau_s: float = Field(0.5, gt=0.0)
    """Time constant (s) of the first-order low-pass filters the deviations are taken from."""
    rest_gyro_deviation_deg_s: float = Field(2.0, gt=0.0)
    """Largest departure (deg/s, vector) of a gyro reading from its low-passed value at rest:
    about 20 times the bundled gyros' noise at their rates (MPU-9250 0.01 deg/s/sqrt(Hz))."""
    rest_accel_deviation_g: float = Field(0.05, gt=0.0)
    """Largest departure (g, vector) of an accelerometer reading from its low-passed value at
    rest: about 15 times the bundled accelerometers' noise (MPU-9250 300 ug/sqrt(Hz)), and
    VQF's 0.5 m/s^2. A tighter 0.02 g was tried: it ends a rest 0.1 s sooner in the
    `thermal` launch's run-up (seed paraglider vario, madgwick's launch tilt max 1.42 against
    1.52 deg), but on BROAD's real recordings, whose still phases are not as still as the
    emulated bench, it finds few rests and learns little bias: madgwick's 6-DOF inclination
    over the 30 trials 3.95 against 2.39 deg (`imuhal evaluate --broad -e madgwick --grid
    madgwick.rest_accel_deviation_g=0.02,0.05 --dof 6`)."""
    rest_min_s: float = Field(1.5, gt=0.0)
    """How long (s) the board must be still without a break before it counts as at rest."""
    rest_first_max_rate_deg_s: float = Field(5.0, gt=0.0)
    """Largest low-passed rate (deg/s, each axis) at the first rest, before any bias is
    learned: the MPU-9250's turn-on zero-rate tolerance (+-5 deg/s), the largest of the
    bundled gyros (the MAX21100's is smaller)."""
    rest_max_rate_deg_s: float = Field(1.0, gt=0.0)
    """Largest low-passed rate (deg/s, each axis) less the learned bias at later rests: the
    bias drifts slowly (about 0.02 deg/s per deg C), a turn does not."""
    rest_bias_tau_s: float = Field(1.0, gt=0.0)
    """Time constant (s) of the gyro bias average at rest: after 3 s at rest the bias is
    known to about 5 % of its change, to a noise of 0.1 deg/s x sqrt(dt / 2 tau) (0.005 deg/s
    at 250 Hz)."""


def rest_params(settings: RestSettings) -> tuple[float, ...]:
    """The settings as the detector's parameters (:func:`~imuhal_filters.common.fast_ahrs.
    rest_update`): on (1.0) or off, the low-pass time constant (s), the squared deviation
    bounds (rad^2/s^2, g^2), the rest time (s), the first and the later rate bounds (rad/s)
    and the bias time constant (s); :data:`REST_OFF` when detection is off."""
    s = settings
    if not s.rest_detection:
        return REST_OFF
    return (1.0, float(s.rest_filter_tau_s), (s.rest_gyro_deviation_deg_s * _DEG) ** 2,
            float(s.rest_accel_deviation_g) ** 2, float(s.rest_min_s),
            s.rest_first_max_rate_deg_s * _DEG, s.rest_max_rate_deg_s * _DEG,
            float(s.rest_bias_tau_s))


REST_START: tuple[float, ...] = (0.0,) * REST_STATE_SIZE
"""A detector's state before its first step."""
