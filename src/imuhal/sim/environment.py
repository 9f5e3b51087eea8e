"""Gravity, the geomagnetic field and the air around the vehicle.

Units: m/s^2, uT, Pa, degC, m, s. The earth field is given as total intensity, inclination
(dip, positive below the horizon) and declination (magnetic north east of true north is
positive), and expressed in NED. The simulated NED frame's north is TRUE north, so a board
with yaw 0 reads a field rotated by the declination.

Pressure follows the ISA troposphere (:mod:`imuhal.core.atmosphere`) above the origin's
altitude, with a sea-level reference that drifts with the weather: a linear trend plus a
slow sinusoid. Temperature is the ISA air temperature plus a day offset; the board (which
is what the sensors' thermometers measure) warms up after power-on along an exponential.
"""

from __future__ import annotations

import math
from typing import Any

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
    """Altitude of the scenario origin (position 0) above mean sea level."""
    sea_level_pa: float = Field(SEA_LEVEL_PRESSURE_PA, gt=50_000, lt=120_000)
    """QNH at t = 0."""
    pressure_drift_pa_per_hour: float = 0.0
    """Slow weather drift of the sea-level pressure (linear trend)."""
    weather_amplitude_pa: float = Field(0.0, ge=0)
    """Amplitude of a slow sinusoidal weather swing of the sea-level pressure."""
    weather_period_s: float = Field(3600.0, gt=0)
    weather_phase_deg: float = 0.0
    temperature_offset_degc: float = 0.0
    """Air temperature minus ISA temperature at the same altitude (a warm day is positive)."""
    board_warmup_degc: float = Field(0.0, ge=0)
    """How much warmer than the air the board ends up after power-on self-heating."""
    board_warmup_tau_s: float = Field(120.0, gt=0)
    """Time constant of that self-heating."""

    # ------------------------------------------------------------------ gravity and field
    def magnetic_field_ned_tuple(self) -> tuple[float, float, float]:
        """Earth field in NED (uT) as plain floats."""
        inc, dec = math.radians(self.inclination_deg), math.radians(self.declination_deg)
        h = self.field_intensity_ut * math.cos(inc)
        return (h * math.cos(dec), h * math.sin(dec), self.field_intensity_ut * math.sin(inc))

    def magnetic_field_ned_ut(self) -> FloatArray:
        return np.array(self.magnetic_field_ned_tuple())

    # ------------------------------------------------------------------ air
    def sea_level_pa_at(self, t_s: float) -> float:
        """The sea-level reference pressure (QNH, Pa) at scenario time ``t_s``."""
        ref = self.sea_level_pa + self.pressure_drift_pa_per_hour * t_s / 3600.0
        if self.weather_amplitude_pa:
            ref += self.weather_amplitude_pa * math.sin(
                2.0 * math.pi * t_s / self.weather_period_s
                + math.radians(self.weather_phase_deg))
        return ref

    def pressure_pa(self, altitude_m: float, t_s: float) -> float:
        """Static pressure at ``altitude_m`` above the origin, at scenario time ``t_s``."""
        return pressure_pa_at_altitude(self.origin_altitude_msl_m + altitude_m,
                                       self.sea_level_pa_at(t_s))

    def air_temperature_degc(self, altitude_m: float) -> float:
        return (temperature_degc_at_altitude(self.origin_altitude_msl_m + altitude_m)
                + self.temperature_offset_degc)

    def temperature_degc(self, altitude_m: float, t_s: float | None = None) -> float:
        """Air temperature at ``altitude_m`` above the origin; with ``t_s``, the board's
        temperature (air plus self-heating since power-on at t = 0)."""
        temp = self.air_temperature_degc(altitude_m)
        if t_s is not None and self.board_warmup_degc:
            temp += self.board_warmup_degc * (1.0 - math.exp(-max(t_s, 0.0)
                                                             / self.board_warmup_tau_s))
        return temp

    # ------------------------------------------------------------------ presets
    @classmethod
    def preset(cls, name: str, **overrides: Any) -> Environment:
        """A named site (see ``ENVIRONMENT_PRESETS``), optionally with fields overridden."""
        try:
            base = ENVIRONMENT_PRESETS[name]
        except KeyError:
            raise ValueError(f"no environment preset {name!r} "
                             f"(known: {', '.join(sorted(ENVIRONMENT_PRESETS))})") from None
        return cls.model_validate({**base, **overrides})


ENVIRONMENT_PRESETS: dict[str, dict[str, Any]] = {
    # Bangalore, 12.97 N 77.59 E, ~920 m MSL: the seed author's home. Field values are rounded
    # from a World Magnetic Model reading for the 2010s (assumed, not read from a source here).
    "bangalore": {"field_intensity_ut": 41.0, "inclination_deg": 13.0,
                  "declination_deg": -1.5, "origin_altitude_msl_m": 920.0},
    # A mid-latitude European site (Munich, 48.1 N 11.6 E, ~520 m MSL); field values rounded
    # from a World Magnetic Model reading for the 2020s (assumed).
    "mid-latitude": {"field_intensity_ut": 48.5, "inclination_deg": 64.0,
                     "declination_deg": 4.0, "origin_altitude_msl_m": 520.0},
    # Sea level, ISA, the conformance data set's field (50 uT, 60 deg dip, no declination).
    "sea-level": {"field_intensity_ut": 50.0, "inclination_deg": 60.0,
                  "declination_deg": 0.0, "origin_altitude_msl_m": 0.0},
}
