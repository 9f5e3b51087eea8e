"""The bmp280 plugin registers its driver and its emulator through the imuhal hooks."""

from __future__ import annotations

from imuhal.plugins.manager import load_registry
from imuhal_chips.bmp280 import plugin


def test_bmp280_plugin_registers_driver_and_emulator_under_one_name() -> None:
    registry = load_registry(entry_point_plugins=False, extra=[("bmp280", plugin)])
    driver = registry.drivers.get("bmp280")
    emulator = registry.emulators.get("bmp280")
    assert driver.name == emulator.chip == "bmp280"
