"""A board switched on in flight (a brown-out reboot, a battery swap in the air) hands out no
climb rate off the truth as valid (issue 26).

vario-kf3 and baro-vario started at climb 0 trusted to 1 cm/s (a board at rest): switched on
38 s into `thermal` they handed out 0.0 in a 1.07 m/s climb, then 2.2 against 1.17, valid
(77 of 976 estimates more than 1 m/s off on seed-gps-vario). They now start with the climb
sigma of a board that may fly and withhold (UNSETTLED) until their own climb sigma is small.
The boards are switched on mid-flight through ``open_emulated(start_s=...)``.
"""

from __future__ import annotations

import math

import pytest

from imuhal.core.errors import ImuhalError
from imuhal.core.samples import PressureSample
from imuhal.emulation import open_emulated
from imuhal.estimation.outputs import EstimateFlag, RejectedEstimate, VerticalEstimate
from imuhal.plugins.manager import Registry, load_registry
from imuhal.profile.bundled import bundled_profiles
from imuhal.profile.loader import load_profile

CLIMB_BOUND_M_S = 1.0
"""A valid climb rate may be this far from the truth (m/s): 4 settled climb sigmas of
vario-kf3 (0.25 m/s), 2.5 of baro-vario (0.4 m/s), which lags a thermal's climb changes."""
IN_THERMAL_S = 38.0
"""`thermal`: circling in the thermal, the truth climbing at 1.07 m/s (the finding's time)."""


@pytest.fixture(scope="module")
def registry() -> Registry:
    return load_registry()


def _vertical(registry: Registry, board: str, start_s: float, seconds: float
              ) -> tuple[list[tuple[VerticalEstimate, float]], list[RejectedEstimate]]:
    """Every vertical estimator's estimates with the true climb rate, and the withheld ones."""
    profile = load_profile(bundled_profiles()[board], registry)
    valid, withheld = [], []
    with open_emulated(profile, registry, seed=1, start_s=start_s) as pipeline:
        truth = pipeline.board.scenario.truth  # type: ignore[attr-defined]  # emulated board
        for event in pipeline.events(seconds):
            if isinstance(event, VerticalEstimate):
                valid.append((event, truth(event.t_ns / 1e9).climb_m_s))
            elif isinstance(event, RejectedEstimate) and event.kind == "vertical":
                withheld.append(event)
    return valid, withheld


def test_start_s_switches_the_emulated_board_on_in_the_middle_of_its_scenario(
        registry: Registry) -> None:
    """Samples carry the scenario's time from the switch-on, and the barometer reads the
    world as it is then (the glider above its launch), not as it was at 0."""
    profile = load_profile(bundled_profiles()["seed-paraglider-vario.yaml"], registry)
    with open_emulated(profile, registry, seed=1, start_s=IN_THERMAL_S) as pipeline:
        truth = pipeline.board.scenario.truth  # type: ignore[attr-defined]  # emulated board
        launch_pa = truth(0.0).pressure_pa
        # the gyro start-up tries for about 10 s on the moving board, yielding nothing
        first = next(e for e in pipeline.events(15.0) if isinstance(e, PressureSample))
    assert first.t_ns >= IN_THERMAL_S * 1e9
    here_pa = truth(first.t_ns / 1e9).pressure_pa
    assert launch_pa - here_pa > 200.0  # the scenario did move on (20 m up): the test can tell
    # within the emulated MS5611's offset and noise (seed 1: 23 Pa)
    assert abs(first.pressure_pa - here_pa) < 100.0


@pytest.mark.parametrize("start_s", [-1.0, math.nan, math.inf])
def test_a_start_time_outside_the_scenario_is_a_one_line_error(
        registry: Registry, start_s: float) -> None:
    profile = load_profile(bundled_profiles()["seed-paraglider-vario.yaml"], registry)
    with pytest.raises(ImuhalError, match="start_s"):
        open_emulated(profile, registry, start_s=start_s)


@pytest.mark.parametrize("board", ["seed-gps-vario.yaml", "seed-paraglider-vario.yaml"])
def test_a_board_switched_on_in_a_thermal_hands_out_no_climb_rate_off_the_truth(
        registry: Registry, board: str) -> None:
    """Switched on circling in the thermal: every vertical estimator (the paraglider's
    baro-only too) first withholds, then every climb rate it hands out is within the bound."""
    valid, withheld = _vertical(registry, board, IN_THERMAL_S, 16.0)
    assert withheld and {w.flags for w in withheld} == {EstimateFlag.UNSETTLED}
    assert valid
    wrong = [(e.source, e.t_ns / 1e9, e.climb_m_s, truth) for e, truth in valid
             if abs(e.climb_m_s - truth) > CLIMB_BOUND_M_S]
    assert wrong == []
    for source in {e.source for e, _ in valid}:
        first = next(e for e, _ in valid if e.source == source)
        later = [w for w in withheld if w.source == source and w.t_ns > first.t_ns]
        assert later == [], f"{source} withheld again after it settled"
