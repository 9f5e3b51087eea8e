"""Settings of ``vario-kf3`` in project units, and their conversion to the cm-unit core."""

from __future__ import annotations

from pydantic import Field

from imuhal.core.atmosphere import SEA_LEVEL_PRESSURE_PA
from imuhal.estimation.base import EstimatorSettings
from imuhal_filters.vario.kf3 import REFERENCES, Kalman3, Kf3Mode

CM_PER_M = 100.0
CM2_PER_M2 = CM_PER_M * CM_PER_M
"""m^2 -> cm^2, and equally (m/s^2)^2 -> (cm/s^2)^2."""


class VarioKf3Settings(EstimatorSettings):
    """Tuning of the 3-state variometer filter (SI units; the core works in cm).

    Leave a variance at None to take the reference value of ``mode`` (``esp32``: altitude
    0.03 m^2 = 300 cm^2, acceleration 5 m^2/s^4 = 50000 cm^2/s^4, bias 1e-4 m^2/s^4 = 1 cm^2/s^4
    per step). See ``imuhal_filters.vario.kf3`` for the modes and the seed's tuning advice:
    ``accel_variance_m2_s4`` is the environment's (air, pilot) acceleration variance, not the
    sensor's noise; start near ``altitude_variance_m2`` numerically; a small
    ``bias_variance_m2_s4`` means a slower start-up.
    """

    mode: Kf3Mode = Kf3Mode.ESP32
    """Reference implementation to reproduce: esp32 (default), avario or y2021."""
    altitude_variance_m2: float | None = Field(default=None, gt=0.0)
    """sigma_zmeas^2 (m^2): barometric altitude noise; see ``estimate_altitude_variance``."""
    accel_variance_m2_s4: float | None = Field(default=None, gt=0.0)
    """sigma_acc^2 ((m/s^2)^2): unmodelled environment acceleration. Ignored by ``avario``,
    which replaces it every step."""
    bias_variance_m2_s4: float | None = Field(default=None, ge=0.0)
    """sigma_accbias^2 ((m/s^2)^2), added once per filter step (not scaled by dt)."""
    initial_bias_m_s2: float = 0.0
    """Accelerometer bias at start-up (m/s^2; true accel = measured - bias)."""
    sea_level_pa: float = Field(default=SEA_LEVEL_PRESSURE_PA, gt=0.0)
    """Pressure reference (QNH, Pa) for pressure -> altitude."""
    max_gap_s: float = Field(default=1.0, gt=0.0)
    """A gap between valid pressure samples longer than this restarts the filter."""
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
