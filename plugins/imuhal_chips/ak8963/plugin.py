"""Entry point of the ak8963 plugin: the AK8963 driver and its register-level emulator."""

from __future__ import annotations

from imuhal.plugins.hookspecs import hookimpl
from imuhal.plugins.registrars import Registrar
from imuhal_chips.ak8963.driver import AK8963Driver
from imuhal_chips.ak8963.emulator import AK8963Emulator


@hookimpl
def imuhal_register_drivers(register: Registrar) -> None:
    register(AK8963Driver)


@hookimpl
def imuhal_register_emulators(register: Registrar) -> None:
    register(AK8963Emulator)
