"""Registers the built-in bus kinds through the same hook any plugin uses."""

from __future__ import annotations

from imuhal.bus.linux_i2c import LinuxI2CFactory
from imuhal.bus.linux_iio import LinuxIIOFactory
from imuhal.bus.linux_spi import LinuxSPIFactory
from imuhal.bus.serial_port import SerialFactory
from imuhal.plugins.hookspecs import hookimpl
from imuhal.plugins.registrars import Registrar


@hookimpl
def imuhal_register_buses(register: Registrar) -> None:
    register(LinuxI2CFactory)
    register(LinuxSPIFactory)
    register(SerialFactory)
    register(LinuxIIOFactory)
