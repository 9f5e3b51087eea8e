"""Entry point of the iio plugin: the driver for chips bound to Linux kernel IIO drivers.

No emulator: the chip behind a kernel driver is the kernel's; tests build a sysfs tree and a
buffer from the kernel's documented ABI instead (tests/chips/test_iio_driver.py).
"""

from __future__ import annotations

from imuhal.plugins.hookspecs import hookimpl
from imuhal.plugins.registrars import Registrar
from imuhal_chips.iio.driver import IIODriver


@hookimpl
def imuhal_register_drivers(register: Registrar) -> None:
    register(IIODriver)
