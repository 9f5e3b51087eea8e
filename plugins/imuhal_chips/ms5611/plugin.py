"""Entry point of the ms5611 plugin: the MS5611-01BA03 barometer driver and its emulator."""

from __future__ import annotations

from imuhal.plugins.hookspecs import hookimpl
from imuhal.plugins.registrars import Registrar
from imuhal_chips.ms5611.driver import MS5611Driver
from imuhal_chips.ms5611.emulator import MS5611Emulator


@hookimpl
def imuhal_register_drivers(register: Registrar) -> None:
    register(MS5611Driver)


@hookimpl
def imuhal_register_emulators(register: Registrar) -> None:
    register(MS5611Emulator)
