"""Default sensor error specs per chip: data only, one entry per chip name.

Values are SI (rad/s, m/s^2, uT, Pa, degC) and are validated by
:func:`imuhal.sim.errors.chip_error_spec`. Each figure names its source:
``chips.md`` (shared/facts/chips.md), a datasheet figure (recalled from the named document,
not in chips.md, so worth re-checking), or ``assumed`` (a plausible value with no source).
Tolerances quoted as +-X are read as 3 sigma for the ``*_std`` per-device draws.
"""

from __future__ import annotations

import math
from typing import Any

DPS = math.pi / 180.0          # rad/s per deg/s
MG = 9.80665e-3                # m/s^2 per milli-g
UG = 9.80665e-6                # m/s^2 per micro-g

CHIP_ERROR_SPECS: dict[str, dict[str, Any]] = {
    "mpu9250": {
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
    },
    "ak8963": {
        "mag": {
            "noise_std": 0.3,                 # assumed: 2 LSB at 0.15 uT/LSB (chips.md LSB)
            "bias_std": 10.0,                 # assumed (sensor offset before calibration)
            "scale_factor_std": 0.01,         # assumed (residual after the ASA correction)
            "cross_axis_std": 0.005,          # assumed
            "hard_iron_ut": (12.0, -7.0, 20.0),  # assumed: a GY-91 board's own magnetisation
            "soft_iron": ((1.02, 0.01, 0.0), (0.01, 0.98, 0.0), (0.0, 0.0, 1.0)),  # assumed
        },
    },
    "hmc5883l": {
        "mag": {
            "noise_std": 0.2,                 # HMC5883L datasheet: noise floor 2 mG
            "bias_std": 2.0,                  # assumed
            "scale_factor_std": 0.05 / 3,     # assumed (self-test limits span +-40 %)
            "cross_axis_std": 0.002,          # HMC5883L datasheet: cross-axis +-0.2 % FS/G
            "hard_iron_ut": (-6.0, 9.0, 4.0),  # assumed: the seed's board and enclosure
            "soft_iron": ((1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0)),  # assumed: none
        },
    },
    "max21100": {
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
    },
    "max21105": {
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
    },
    "ms5611": {
        "pressure": {
            "noise_std": 1.2,                 # chips.md: RMS resolution 0.012 mbar at OSR 4096
            # (0.065 mbar = 6.5 Pa at OSR 256: override for lower OSR)
            "bias_std": 150 / 3,              # MS5611 datasheet: absolute accuracy +-1.5 mbar
            "temp_coeff": 0.0,                # assumed: the PROM compensation removes it
        },
        "temperature": {
            "noise_std": 0.002,               # chips.md: RMS resolution 0.002 degC at OSR 4096
            "bias_std": 0.8 / 3,              # MS5611 datasheet: +-0.8 degC at 20 degC
        },
    },
    "bmp280": {
        "pressure": {
            "noise_std": 1.3,                 # BMP280 datasheet: RMS noise 1.3 Pa, ultra high
            # resolution, filter off (chips.md lists only resolution: 0.16 Pa at x16)
            "bias_std": 100 / 3,              # BMP280 datasheet: absolute accuracy +-1 hPa
            "temp_coeff": 0.5,                # assumed (datasheet TCO +-1.5 Pa/K)
        },
        "temperature": {
            "noise_std": 0.005,               # assumed (chips.md: 0.005 degC resolution at x1)
            "bias_std": 0.5 / 3,              # BMP280 datasheet: +-0.5 degC at 25 degC
        },
    },
}
