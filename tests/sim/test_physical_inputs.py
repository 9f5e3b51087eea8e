"""PhysicalInputs.build: the emulated board's fast way to make a chip's inputs."""

from __future__ import annotations

import dataclasses

import pytest

from imuhal.sim.inputs import NO_OTHER, PhysicalInputs


def test_build_gives_the_object_the_keyword_constructor_gives() -> None:
    built = PhysicalInputs.build((1.0, -2.0, 9.81), None, (20.0, 0.5, -40.0), 101325.0,
                                 21.5, (1.0, 2.0, -300.0), None, NO_OTHER)
    keyword = PhysicalInputs(specific_force_m_s2=(1.0, -2.0, 9.81),
                             magnetic_field_ut=(20.0, 0.5, -40.0), pressure_pa=101325.0,
                             temperature_degc=21.5, position_ned_m=(1.0, 2.0, -300.0))
    assert built == keyword
    assert repr(built) == repr(keyword)


def test_built_inputs_stay_frozen() -> None:
    built = PhysicalInputs.build(None, None, None, 1.0, 2.0, None, None, NO_OTHER)
    with pytest.raises(dataclasses.FrozenInstanceError):
        built.pressure_pa = 3.0  # type: ignore[misc]
