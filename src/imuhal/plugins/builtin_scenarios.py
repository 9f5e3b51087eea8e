"""Registers the built-in scenarios through the same hook any plugin uses."""

from __future__ import annotations

from imuhal.plugins.hookspecs import hookimpl
from imuhal.plugins.registrars import Registrar
from imuhal.sim.builtin import BUILTIN_SCENARIOS


@hookimpl
def imuhal_register_scenarios(register: Registrar) -> None:
    for cls in BUILTIN_SCENARIOS:
        register(cls)
