"""Rest detection on the bundled seed paraglider board (issue 27): at rest on the launch, never
in flight.

The board as `imuhal run --skip-calibration` flies it (chips with their datasheet errors, the
profile's start-up gyro offsets), `thermal` seed 1: standing until 5 s, a 3 s run-up, then
turns in the thermal. The profile's madgwick is at rest within its first 2.5 s and
leaves rest within 0.3 s of the run-up's start; after that nothing in the flight (the
turns, the straight glides in between) passes for rest, and the bias it learned is the
start-up offsets' residual (under 0.05 deg/s per axis).
"""

from __future__ import annotations

import math

import pytest

from imuhal.emulation import open_emulated
from imuhal.estimation.outputs import AttitudeEstimate
from imuhal.plugins.manager import load_registry
from imuhal.profile.bundled import bundled_profiles
from imuhal.profile.loader import load_profile

RUN_UP_S = 5.0


@pytest.mark.slow
def test_the_seed_board_is_at_rest_on_the_launch_and_never_in_flight() -> None:
    registry = load_registry()
    profile = load_profile(bundled_profiles()["seed-paraglider-vario.yaml"], registry)
    rest_times: list[float] = []
    last: AttitudeEstimate | None = None
    with open_emulated(profile, registry, scenario="thermal", seed=1) as pipeline:
        for event in pipeline.events(60.0):
            if isinstance(event, AttitudeEstimate) and event.source == "ahrs":
                last = event
                if event.diagnostics["at_rest"]:
                    rest_times.append(event.t_ns / 1e9)
    assert rest_times and min(rest_times) < 2.5
    assert max(rest_times) < RUN_UP_S + 0.3
    assert last is not None
    assert all(abs(math.degrees(b)) < 0.05 for b in last.diagnostics["rest_gyro_bias_rad_s"])
