"""The mpu9250 plugin registers its driver and its emulator through the imuhal hooks."""

from __future__ import annotations

from imuhal.plugins.manager import load_registry
from imuhal_chips.mpu9250 import plugin


def test_mpu9250_plugin_registers_driver_and_emulator_under_one_name() -> None:
    registry = load_registry(entry_point_plugins=False, extra=[("mpu9250", plugin)])
    driver = registry.drivers.get("mpu9250")
    emulator = registry.emulators.get("mpu9250")
    assert driver.name == emulator.chip == "mpu9250"
