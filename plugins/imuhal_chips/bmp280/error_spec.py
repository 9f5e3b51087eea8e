"""Datasheet noise and bias figures of the BMP280 for the simulator (data only; units,
field meanings and the source tags used in the comments: docs/simulation.md)."""

from __future__ import annotations

from typing import Any

BMP280_ERROR_SPEC: dict[str, Any] = {
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
}
