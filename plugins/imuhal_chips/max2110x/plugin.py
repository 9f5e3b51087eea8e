"""Entry point of the max2110x plugin: MAX21100 and MAX21105 drivers and emulators."""

from __future__ import annotations

from imuhal.plugins.hookspecs import hookimpl
from imuhal.plugins.registrars import Registrar
from imuhal_chips.max2110x.driver import Max21100Driver, Max21105Driver
from imuhal_chips.max2110x.emulator import Max21100Emulator, Max21105Emulator


@hookimpl
def imuhal_register_drivers(register: Registrar) -> None:
    register(Max21100Driver)
    register(Max21105Driver)


@hookimpl
def imuhal_register_emulators(register: Registrar) -> None:
    register(Max21100Emulator)
    register(Max21105Emulator)
