"""Settings of ``vario-kf3`` in project units, and their conversion to the cm-unit core."""

from __future__ import annotations

from typing import Any, ClassVar

from pydantic import Field

from imuhal.core.atmosphere import SEA_LEVEL_PRESSURE_PA
from imuhal_filters.common.presets import PresetSettings
from imuhal_filters.vario.kf3 import REFERENCES, Kalman3, Kf3Mode

CM_PER_M = 100.0
CM2_PER_M2 = CM_PER_M * CM_PER_M
"""m^2 -> cm^2, and equally (m/s^2)^2 -> (cm/s^2)^2."""


DEFAULT_ALTITUDE_VARIANCE_M2 = 0.015
"""The seed boards' MS5611 at OSR 4096, 50 Hz: 1.5 s of emulated altitude at rest (the seed's
tuning recipe, ``estimate_altitude_variance``) gave 0.0153 m^2, 0.0185 m^2 with today's
emulator timing (docs/estimators.md)."""
DEFAULT_ACCEL_VARIANCE_M2_S4 = 0.05
"""Chosen on the emulated seed board (docs/scripts/flight_benchmark.py): quiet at rest and
still within 0.2 s of a 2 m/s climb step; see the lag/quietness table in docs/estimators.md."""
DEFAULT_BIAS_VARIANCE_M2_S4 = 1e-6
"""Per barometer step (1e-2 cm^2/s^4; esp32: 1 cm^2/s^4): at 50 Hz the reference value lets
the bias wander enough to double the climb noise at rest (docs/estimators.md)."""
UNKNOWN_CLIMB_SIGMA_M_S = 5.0
"""The climb rate's standard deviation at start-up and after a restart after a gap (m/s):
nobody measured it, and the board may be flying (a brown-out reboot, a battery swap in the
air). 5 m/s covers a paraglider's or a glider's strong thermals and ordinary sink (3-5 m/s; a
spiral dive's 15-20 m/s is beyond one sigma, not beyond the filter) and the climb-outs of the
bundled rc-flight scenario."""
_REFERENCE: dict[str, Any] = {"altitude_variance_m2": None, "accel_variance_m2_s4": None,
                              "bias_variance_m2_s4": None, "innovation_gate_sigma": None,
                              "initial_climb_sigma_m_s": None}


class VarioKf3Settings(PresetSettings):
    """Tuning of the 3-state variometer filter (SI units; the core works in cm).

    Defaults are tuned on the seed boards' barometer and accelerometer (docs/estimators.md);
    ``preset: reference`` (or ``seed``) takes the reference values of ``mode`` (``esp32``:
    altitude 0.03 m^2 = 300 cm^2, acceleration 5 m^2/s^4 = 50000 cm^2/s^4, bias 1e-4 m^2/s^4
    = 1 cm^2/s^4 per step) and no innovation gate. A variance left at None takes the
    reference value of ``mode``. See ``imuhal_filters.vario.kf3`` for the modes and the
    seed's tuning advice: ``accel_variance_m2_s4`` is the environment's (air, pilot)
    acceleration variance, not the sensor's noise; it trades lag for quietness.
    """

    PRESETS: ClassVar[dict[str, dict[str, Any]]] = {"reference": _REFERENCE, "seed": _REFERENCE}

    mode: Kf3Mode = Kf3Mode.ESP32
    """Reference implementation to reproduce: esp32 (default), avario or y2021."""
    altitude_variance_m2: float | None = Field(default=DEFAULT_ALTITUDE_VARIANCE_M2, gt=0.0)
    """sigma_zmeas^2 (m^2): barometric altitude noise; see ``estimate_altitude_variance``."""
    accel_variance_m2_s4: float | None = Field(default=DEFAULT_ACCEL_VARIANCE_M2_S4, gt=0.0)
    """sigma_acc^2 ((m/s^2)^2): unmodelled environment acceleration; smaller is quieter at
    rest and slower to follow what the accelerometer misses. Ignored by ``avario``, which
    replaces it every step."""
    bias_variance_m2_s4: float | None = Field(default=DEFAULT_BIAS_VARIANCE_M2_S4, ge=0.0)
    """sigma_accbias^2 ((m/s^2)^2), added once per filter step (not scaled by dt)."""
    initial_climb_sigma_m_s: float | None = Field(default=UNKNOWN_CLIMB_SIGMA_M_S, gt=0.0)
    """Sigma of the climb rate at start-up (m/s; the filter starts at climb 0). The estimates
    are withheld (UNSETTLED) until the filter's own climb sigma is under its settled bound
    (0.25 m/s), so a board switched on in flight never hands out climb 0 as valid. None: the
    reference value of ``mode`` (esp32 and avario 1 cm/s, y2021 0.39 m/s: a board at rest)."""
    settled_climb_sigma_m_s: float = Field(default=0.25, gt=0.0)
    """After a start or a restart, estimates are withheld (UNSETTLED) until the filter's own
    climb sigma is under this (m/s). It must lie above the tuning's steady state (the
    defaults: 0.036 m/s at 50 Hz, 0.048 m/s at 25 Hz), or the filter withholds for good."""
    initial_bias_m_s2: float = 0.0
    """Accelerometer bias at start-up (m/s^2; true accel = measured - bias)."""
    sea_level_pa: float = Field(default=SEA_LEVEL_PRESSURE_PA, gt=0.0)
    """Pressure reference (QNH, Pa) for pressure -> altitude."""
    innovation_gate_sigma: float | None = Field(default=5.0, gt=0.0)
    """A barometric altitude further than this many standard deviations of the innovation
    (sqrt(P_zz + sigma_zmeas^2)) from the prediction is not fused (counted as
    ``gated``): one wild but in-range pressure sample must not throw the climb rate.
    None: no gate (the references)."""
    innovation_gate_min_m: float = Field(default=1.0, ge=0.0)
    """The gate never closes for innovations within this (m): a barometer noisier than its
    configured variance must not be gated on ordinary noise."""
    gate_reacquire_s: float = Field(default=0.3, gt=0.0)
    """Altitudes rejected without a break for this long are a real level change (a jump the
    accelerometer did not see, a QNH change): the filter re-acquires the new level."""
    max_gap_s: float = Field(default=1.0, gt=0.0)
    """A gap between valid pressure samples longer than this restarts the filter."""
    max_dt_s: float = Field(default=0.25, gt=0.0)
    """A step between valid pressure samples longer than this is predicted over only when
    the pipeline counted the pressures lost in it (a StreamGap, imuhal.core.gaps); one that
    no counted loss explains (a time stamp that jumped) restarts the filter instead."""
    attitude_source: str | None = None
    """Use only AttitudeEstimates from this estimator instance (None: any), so two AHRS in
    one pipeline do not feed the same acceleration twice."""


def configured_core(settings: VarioKf3Settings, z0_m: float) -> Kalman3:
    """A Kalman3 in ``settings.mode`` configured from SI settings, starting at ``z0_m``."""
    ref = REFERENCES[settings.mode]

    def cm2(value_si: float | None, reference_cm: float) -> float:
        return reference_cm if value_si is None else value_si * CM2_PER_M2

    kf = Kalman3(settings.mode)
    kf.configure(
        cm2(settings.altitude_variance_m2, ref.z_meas_variance),
        cm2(settings.accel_variance_m2_s4, ref.accel_variance),
        cm2(settings.bias_variance_m2_s4, ref.bias_variance),
        z0=z0_m * CM_PER_M,
        v0=0.0,
        bias0=settings.initial_bias_m_s2 * CM_PER_M,
    )
    return kf


def initial_climb_variance_cm2_s2(settings: VarioKf3Settings) -> float:
    """The climb rate's variance at start-up ((cm/s)^2): ``initial_climb_sigma_m_s``, or the
    mode's reference P0 when it is None."""
    sigma = settings.initial_climb_sigma_m_s
    if sigma is None:
        return REFERENCES[settings.mode].p0_diag[1]
    return (sigma * CM_PER_M) ** 2
