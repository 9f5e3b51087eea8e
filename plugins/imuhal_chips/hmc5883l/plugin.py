"""Entry point of the hmc5883l plugin: the HMC5883L driver and its emulator."""

from __future__ import annotations

from imuhal.plugins.hookspecs import hookimpl
from imuhal.plugins.registrars import Registrar
from imuhal_chips.hmc5883l.driver import Hmc5883lDriver
from imuhal_chips.hmc5883l.emulator import Hmc5883lEmulator


@hookimpl
def imuhal_register_drivers(register: Registrar) -> None:
    register(Hmc5883lDriver)


@hookimpl
def imuhal_register_emulators(register: Registrar) -> None:
    register(Hmc5883lEmulator)
