"""Every bundled profile validates and runs emulated with every chip active."""

from __future__ import annotations

import pytest

from imuhal.core.samples import Sample
from imuhal.emulation import open_emulated
from imuhal.estimation.outputs import Estimate
from imuhal.plugins.manager import Registry, load_registry
from imuhal.profile.loader import load_profile
from imuhal.profiles_dir import bundled_profiles

PROFILES = sorted(bundled_profiles())


@pytest.fixture(scope="module")
def installed() -> Registry:
    return load_registry()


def test_the_three_seed_and_module_boards_are_bundled() -> None:
    assert set(PROFILES) >= {"seed-paraglider-vario.yaml", "seed-rc-vario.yaml", "gy91.yaml"}


@pytest.mark.parametrize("name", PROFILES)
def test_profile_runs_emulated_with_every_device_and_estimator_producing(
    installed: Registry, name: str
) -> None:
    profile = load_profile(bundled_profiles()[name], installed)
    with open_emulated(profile, installed, scenario=profile.emulation.scenario) as p:
        events = list(p.events(3.0))
        summary = p.summary()
    for device in profile.devices:
        produced = [e for e in events if isinstance(e, Sample) and e.device == device]
        assert produced, f"{device} produced nothing"
        assert all(e.valid for e in produced), summary.flagged[device]
        assert summary.bus_errors[device] == 0
    for estimator in profile.estimators:
        assert any(isinstance(e, Estimate) and e.source == estimator for e in events), estimator
    assert summary.warnings == []
