"""Registers the built-in scenarios through the same hook any plugin uses."""

from __future__ import annotations

from imuhal.plugins.hookspecs import hookimpl
from imuhal.plugins.registrars import Registrar
from imuhal.sim.thermal import ThermalScenario


@hookimpl
def imuhal_register_scenarios(register: Registrar) -> None:
    register(ThermalScenario)
