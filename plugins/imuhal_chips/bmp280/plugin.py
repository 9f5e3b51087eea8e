"""Entry point of the bmp280 plugin: the BMP280 driver and its register-level emulator."""

from __future__ import annotations

from imuhal.plugins.hookspecs import hookimpl
from imuhal.plugins.registrars import Registrar
from imuhal_chips.bmp280.driver import BMP280Driver
from imuhal_chips.bmp280.emulator import BMP280Emulator


@hookimpl
def imuhal_register_drivers(register: Registrar) -> None:
    register(BMP280Driver)


@hookimpl
def imuhal_register_emulators(register: Registrar) -> None:
    register(BMP280Emulator)
