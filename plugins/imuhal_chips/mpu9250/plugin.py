"""Entry point of the mpu9250 plugin: the MPU-9250 driver and its register-level emulator."""

from __future__ import annotations

from imuhal.plugins.hookspecs import hookimpl
from imuhal.plugins.registrars import Registrar
from imuhal_chips.mpu9250.driver import MPU9250Driver
from imuhal_chips.mpu9250.emulator import MPU9250Emulator


@hookimpl
def imuhal_register_drivers(register: Registrar) -> None:
    register(MPU9250Driver)


@hookimpl
def imuhal_register_emulators(register: Registrar) -> None:
    register(MPU9250Emulator)
