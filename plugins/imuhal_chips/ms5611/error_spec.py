"""Datasheet noise and bias figures of the MS5611 for the simulator (data only; units,
field meanings and the source tags used in the comments: docs/simulation.md)."""

from __future__ import annotations

from typing import Any

MS5611_ERROR_SPEC: dict[str, Any] = {
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
}
