"""Datasheet noise and bias figures of the AK8963 for the simulator (data only; units,
field meanings and the source tags used in the comments: docs/simulation.md)."""

from __future__ import annotations

from typing import Any

AK8963_ERROR_SPEC: dict[str, Any] = {
    "mag": {
        "noise_std": 0.3,                 # assumed: 2 LSB at 0.15 uT/LSB (chips.md LSB)
        "bias_std": 10.0,                 # assumed (sensor offset before calibration)
        "scale_factor_std": 0.01,         # assumed (residual after the ASA correction)
        "cross_axis_std": 0.005,          # assumed
        "hard_iron_ut": (12.0, -7.0, 20.0),  # assumed: a GY-91 board's own magnetisation
        "soft_iron": ((1.02, 0.01, 0.0), (0.01, 0.98, 0.0), (0.0, 0.0, 1.0)),  # assumed
    },
}
