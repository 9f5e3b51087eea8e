"""Datasheet noise and bias figures of the MPU9250 for the simulator (data only; units,
field meanings and the source tags used in the comments: docs/simulation.md)."""

from __future__ import annotations

import math
from typing import Any

DPS = math.pi / 180.0          # rad/s per deg/s
MG = 9.80665e-3                # m/s^2 per milli-g
UG = 9.80665e-6                # m/s^2 per micro-g

MPU9250_ERROR_SPEC: dict[str, Any] = {
    "gyro": {
        "noise_density": 0.01 * DPS,      # MPU-9250 product spec: 0.01 dps/sqrt(Hz)
        "bias_std": 5.0 / 3 * DPS,        # product spec: initial ZRO tolerance +-5 dps
        "bias_temp_coeff": (0.02 * DPS, -0.015 * DPS, 0.01 * DPS),  # assumed (spec
        # allows +-30 dps over -40..85 degC)
        "bias_random_walk": 0.001 * DPS,  # assumed: 0.001 dps/sqrt(s)
        "scale_factor_std": 0.03 / 3,     # product spec: sensitivity tolerance +-3 %
        "cross_axis_std": 0.02 / 3,       # product spec: cross-axis sensitivity +-2 %
    },
    "accel": {
        "noise_density": 300 * UG,        # product spec: 300 ug/sqrt(Hz)
        "bias_std": 60 / 3 * MG,          # product spec: zero-g offset +-60 mg (x, y)
        "bias_temp_coeff": (0.5 * MG, -0.5 * MG, 1.0 * MG),  # assumed (spec +-1.5 mg/degC)
        "bias_random_walk": 1e-4,         # assumed: 0.1 mm/s^2/sqrt(s)
        "scale_factor_std": 0.03 / 3,     # product spec: sensitivity tolerance +-3 %
        "cross_axis_std": 0.02 / 3,       # product spec: cross-axis sensitivity +-2 %
    },
    "temperature": {
        "noise_std": 0.01,                # assumed
        "bias_std": 1.0,                  # assumed (die temperature vs. calibration)
    },
}
