"""The International Standard Atmosphere (troposphere, 0-11 km), both directions.

Used by the barometric estimators (pressure -> altitude) and by the simulator
(altitude -> pressure). Altitude is geopotential metres above the level where the pressure
equals the reference ``sea_level_pa`` (QNH); 101325 Pa gives standard pressure altitude.
"""

from __future__ import annotations

import math

SEA_LEVEL_PRESSURE_PA = 101_325.0
SEA_LEVEL_TEMPERATURE_K = 288.15
LAPSE_RATE_K_PER_M = 0.0065
GAS_CONSTANT_AIR_J_KG_K = 287.052_87
STANDARD_GRAVITY_M_S2 = 9.806_65
_EXPONENT = STANDARD_GRAVITY_M_S2 / (GAS_CONSTANT_AIR_J_KG_K * LAPSE_RATE_K_PER_M)  # ~5.2559


def pressure_pa_at_altitude(
    altitude_m: float, sea_level_pa: float = SEA_LEVEL_PRESSURE_PA
) -> float:
    """Static pressure (Pa) at ``altitude_m`` in the ISA troposphere."""
    ratio = 1.0 - LAPSE_RATE_K_PER_M * altitude_m / SEA_LEVEL_TEMPERATURE_K
    if ratio <= 0:
        raise ValueError(f"altitude {altitude_m} m is outside the troposphere model")
    return float(sea_level_pa * ratio**_EXPONENT)


def altitude_m_from_pressure(
    pressure_pa: float, sea_level_pa: float = SEA_LEVEL_PRESSURE_PA
) -> float:
    """Altitude (m) at which the ISA troposphere has ``pressure_pa``."""
    if pressure_pa <= 0 or not math.isfinite(pressure_pa):
        raise ValueError(f"pressure must be a positive finite number of Pa, got {pressure_pa}")
    return float(SEA_LEVEL_TEMPERATURE_K / LAPSE_RATE_K_PER_M * (
        1.0 - (pressure_pa / sea_level_pa) ** (1.0 / _EXPONENT)
    ))


def temperature_degc_at_altitude(altitude_m: float) -> float:
    """ISA air temperature (degC) at ``altitude_m``."""
    return SEA_LEVEL_TEMPERATURE_K - LAPSE_RATE_K_PER_M * altitude_m - 273.15
