"""A chip handed its inputs at its host's polls but measuring at only some of them (the
MS5611 converts at one poll in three on the seed board) gets them computed when it reads
them (``ChipEmulator.set_physics_later``): the same values, only fewer truths computed."""

from __future__ import annotations

from collections.abc import Iterator

import pytest

from imuhal.core.clock import SimulatedClock
from imuhal.emulation import open_emulated
from imuhal.emulation.board import EmulatedBoard
from imuhal.plugins.manager import Registry, load_registry
from imuhal.profile.bundled import bundled_profiles
from imuhal.profile.loader import load_profile
from imuhal.sim.inputs import PhysicalInputs
from imuhal_chips.ms5611.emulator import MS5611Emulator


@pytest.fixture(scope="module")
def registry() -> Registry:
    return load_registry()


def test_inputs_handed_later_are_computed_only_when_read():
    chip = MS5611Emulator(clock=SimulatedClock())
    computed: list[float] = []

    def at(pressure: float) -> PhysicalInputs:
        computed.append(pressure)
        return PhysicalInputs(pressure_pa=pressure, temperature_degc=20.0)

    chip.set_physics_later(lambda: at(90_000.0))
    chip.set_physics_later(lambda: at(91_000.0))  # replaces the first, never read
    assert computed == []
    assert chip.physics.pressure_pa == 91_000.0
    assert chip.physics.pressure_pa == 91_000.0
    assert computed == [91_000.0]


def test_a_frozen_chip_keeps_what_it_had_rather_than_inputs_handed_later():
    chip = MS5611Emulator(clock=SimulatedClock())
    chip.set_physics(PhysicalInputs(pressure_pa=95_000.0, temperature_degc=20.0))
    chip.frozen = True
    chip.set_physics_later(lambda: PhysicalInputs(pressure_pa=1.0, temperature_degc=1.0))
    assert chip.physics.pressure_pa == 95_000.0


def _events(registry: Registry, *, later: bool) -> Iterator[str]:
    profile = load_profile(bundled_profiles()["seed-paraglider-vario.yaml"], registry)
    with open_emulated(profile, registry, scenario="thermal", seed=3,
                       scenario_params={"launch_s": 0.0}, calibrated=False) as p:
        device = EmulatedBoard.of(p)._devices["baro"]
        assert device.later  # the MS5611 keeps the base class's set_physics
        device.later = later
        yield from (repr(e) for e in p.events(3.0))


def test_the_barometer_reads_the_same_values_as_when_handed_them_at_every_poll(
        registry: Registry):
    assert list(_events(registry, later=True)) == list(_events(registry, later=False))
