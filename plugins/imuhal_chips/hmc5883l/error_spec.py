"""Datasheet noise and bias figures of the HMC5883L for the simulator (data only; units,
field meanings and the source tags used in the comments: docs/simulation.md)."""

from __future__ import annotations

from typing import Any

HMC5883L_ERROR_SPEC: dict[str, Any] = {
    "mag": {
        "noise_std": 0.2,                 # HMC5883L datasheet: noise floor 2 mG
        "bias_std": 2.0,                  # assumed
        "scale_factor_std": 0.05 / 3,     # assumed (self-test limits span +-40 %)
        "cross_axis_std": 0.002,          # HMC5883L datasheet: cross-axis +-0.2 % FS/G
        "hard_iron_ut": (-6.0, 9.0, 4.0),  # assumed: the seed's board and enclosure
        "soft_iron": ((1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0)),  # assumed: none
    },
}
