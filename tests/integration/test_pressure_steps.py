"""A pressure step no flight makes is IMPLAUSIBLE (issue 26, the fault matrix's MS5611 finding).

The MS5611 compensates each pressure (D1) with the temperature (D2) converted before it. A
wild temperature seen by the pressure element during a D1 conversion, while that D2 was
honest, gives a pressure in range and 32 kPa off (58.9 against 90.7 kPa on the seed
paraglider vario): no range check sees it. The driver bounds how far a pressure may move
from the last valid one by the fastest vertical speed (``max_vertical_speed_m_s``) at the
steepest gradient plus the noise; honest flights, however steep, are never flagged.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import pytest
import yaml

from imuhal.core.samples import PressureSample, SampleFlag
from imuhal.emulation import open_emulated
from imuhal.emulation.faults import FaultSpec, WildValue
from imuhal.plugins.manager import Registry, load_registry
from imuhal.profile.bundled import bundled_profiles
from imuhal.profile.loader import parse_profile

TOLERANCE_PA = 60.0
"""The MS5611 error model's bias (seed 1) and noise stay well within this of the truth."""


@pytest.fixture(scope="module")
def registry() -> Registry:
    return load_registry()


def _pressures(registry: Registry, board: str, seconds: float, faults: Sequence[FaultSpec] = (),
               scenario: str | None = None, **baro: Any) -> list[tuple[PressureSample, float]]:
    """Every barometer pressure of ``board`` with the truth at its time stamp."""
    doc = yaml.safe_load(bundled_profiles()[board].read_text())
    doc["devices"]["baro"]["settings"].update(baro)
    profile = parse_profile(yaml.safe_dump(doc, sort_keys=False), board, registry)
    out = []
    with open_emulated(profile, registry, seed=1, faults=list(faults),
                       **({"scenario": scenario} if scenario else {})) as pipeline:
        truth = pipeline.board.scenario.truth  # type: ignore[attr-defined]  # emulated board
        for event in pipeline.events(seconds):
            if isinstance(event, PressureSample) and event.device == "baro":
                out.append((event, truth(event.t_ns / 1e9).pressure_pa))
    return out


WILD_TEMPERATURES = [WildValue(device="baro", channel="temperature", value=1e8,
                               start_s=1.0 + 0.2 * i) for i in range(10)]
"""A wild temperature every 0.2 s: some fall in a D2 conversion (the temperature is out of
range, flagged), some in a D1 conversion after an honest D2 (the case no range sees)."""


def test_a_wild_temperature_during_a_pressure_conversion_is_never_a_valid_pressure(
        registry: Registry) -> None:
    pressures = _pressures(registry, "seed-paraglider-vario.yaml", 3.5, WILD_TEMPERATURES)
    wrong = [(s.t_ns / 1e9, s.pressure_pa, truth) for s, truth in pressures
             if s.valid and abs(s.pressure_pa - truth) > TOLERANCE_PA]
    assert wrong == []
    implausible = [s for s, truth in pressures if s.flags & SampleFlag.IMPLAUSIBLE]
    assert implausible and all(abs(s.pressure_pa - truth) > 10_000 for s, truth in
                               pressures if s.flags & SampleFlag.IMPLAUSIBLE)
    # each wild temperature costs its own reading only: the honest one after it is valid
    assert sum(not s.valid for s, _ in pressures) <= len(WILD_TEMPERATURES)


@pytest.mark.parametrize(("board", "scenario"), [
    ("seed-paraglider-vario.yaml", "thermal"), ("seed-rc-vario.yaml", "rc-flight")])
def test_honest_pressures_are_never_implausible_even_at_a_paragliders_speed_limit(
        registry: Registry, board: str, scenario: str) -> None:
    """The bound lowered to 15 m/s (a paraglider's fastest spiral) still passes every honest
    reading of a thermal flight and of an RC plane's climbs and dives, with noise."""
    pressures = _pressures(registry, board, 20.0, scenario=scenario,
                           max_vertical_speed_m_s=15.0)
    assert len(pressures) > 700
    assert not [s for s, _ in pressures if s.flags & SampleFlag.IMPLAUSIBLE]
