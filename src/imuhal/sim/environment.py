"""Gravity, the geomagnetic field and the air around the vehicle."""

from __future__ import annotations

import math

import numpy as np
from pydantic import Field

from imuhal.core.atmosphere import (
    SEA_LEVEL_PRESSURE_PA,
    STANDARD_GRAVITY_M_S2,
    pressure_pa_at_altitude,
    temperature_degc_at_altitude,
)
from imuhal.core.frames import FloatArray
from imuhal.sim.scenario import ScenarioParams


class Environment(ScenarioParams):
    """Where the flight happens. Defaults: near Bangalore (the seed's home), 920 m MSL."""

    gravity_m_s2: float = Field(STANDARD_GRAVITY_M_S2, gt=0)
    field_intensity_ut: float = Field(41.0, gt=0)
    inclination_deg: float = Field(13.0, ge=-90, le=90)
    """Dip angle, positive when the field points below the horizon (northern hemisphere)."""
    declination_deg: float = Field(-1.5, ge=-180, le=180)
    """Magnetic north east of true north is positive."""
    origin_altitude_msl_m: float = 920.0
    sea_level_pa: float = Field(SEA_LEVEL_PRESSURE_PA, gt=50_000, lt=120_000)
    pressure_drift_pa_per_hour: float = 0.0
    """Slow weather drift of the sea-level pressure."""

    def gravity_ned(self) -> FloatArray:
        return np.array([0.0, 0.0, self.gravity_m_s2])

    def magnetic_field_ned_ut(self) -> FloatArray:
        inc, dec = math.radians(self.inclination_deg), math.radians(self.declination_deg)
        h = self.field_intensity_ut * math.cos(inc)
        return np.array([h * math.cos(dec), h * math.sin(dec),
                         self.field_intensity_ut * math.sin(inc)])

    def pressure_pa(self, altitude_m: float, t_s: float) -> float:
        """Static pressure at ``altitude_m`` above the origin, at scenario time ``t_s``."""
        reference = self.sea_level_pa + self.pressure_drift_pa_per_hour * t_s / 3600.0
        return pressure_pa_at_altitude(self.origin_altitude_msl_m + altitude_m, reference)

    def temperature_degc(self, altitude_m: float) -> float:
        return temperature_degc_at_altitude(self.origin_altitude_msl_m + altitude_m)
