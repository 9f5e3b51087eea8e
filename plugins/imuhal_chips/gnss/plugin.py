"""Entry point of the gnss plugin: the NMEA/UBX receiver driver and its byte-stream emulator."""

from __future__ import annotations

from imuhal.plugins.hookspecs import hookimpl
from imuhal.plugins.registrars import Registrar
from imuhal_chips.gnss.driver import GnssDriver
from imuhal_chips.gnss.emulator import GnssEmulator


@hookimpl
def imuhal_register_drivers(register: Registrar) -> None:
    register(GnssDriver)


@hookimpl
def imuhal_register_emulators(register: Registrar) -> None:
    register(GnssEmulator)
