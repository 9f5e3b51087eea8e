"""Datasheet noise and bias figures of the MAX21100 and MAX21105 for the simulator (data
only; units, field meanings and the source tags used in the comments: docs/simulation.md)."""

from __future__ import annotations

import math
from typing import Any

DPS = math.pi / 180.0          # rad/s per deg/s
MG = 9.80665e-3                # m/s^2 per milli-g
UG = 9.80665e-6                # m/s^2 per micro-g

MAX21100_ERROR_SPEC: dict[str, Any] = {
    "gyro": {
        "noise_density": 0.005 * DPS,     # assumed (seed: "rather low gyro noise")
        "bias_std": 1.0 * DPS,            # assumed
        "bias_temp_coeff": (0.01 * DPS, 0.01 * DPS, -0.01 * DPS),  # assumed
        "bias_random_walk": 0.0005 * DPS,  # assumed (seed: "low ... drift")
        "scale_factor_std": 0.01,         # assumed
        "cross_axis_std": 0.005,          # assumed
    },
    "accel": {
        "noise_density": 150 * UG,        # assumed
        "bias_std": 20 * MG,              # assumed
        "bias_temp_coeff": (0.3 * MG, 0.3 * MG, -0.5 * MG),  # assumed
        "bias_random_walk": 1e-4,         # assumed
        "scale_factor_std": 0.01,         # assumed
        "cross_axis_std": 0.005,          # assumed
    },
    "temperature": {"noise_std": 0.02, "bias_std": 1.0},  # assumed
}


MAX21105_ERROR_SPEC: dict[str, Any] = {
    "gyro": {
        "noise_density": 0.005 * DPS,     # assumed (seed: same low noise as MAX21100)
        "bias_std": 1.0 * DPS,            # assumed
        "bias_temp_coeff": (0.01 * DPS, -0.01 * DPS, 0.01 * DPS),  # assumed
        "bias_random_walk": 0.0005 * DPS,  # assumed
        "scale_factor_std": 0.01,         # assumed
        "cross_axis_std": 0.005,          # assumed
    },
    "accel": {
        "noise_density": 150 * UG,        # assumed
        "bias_std": 20 * MG,              # assumed
        "bias_temp_coeff": (0.3 * MG, -0.3 * MG, 0.5 * MG),  # assumed
        "bias_random_walk": 1e-4,         # assumed
        "scale_factor_std": 0.01,         # assumed
        "cross_axis_std": 0.005,          # assumed
    },
    "temperature": {"noise_std": 0.02, "bias_std": 1.0},  # assumed
}
