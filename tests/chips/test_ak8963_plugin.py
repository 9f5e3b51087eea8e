"""The ak8963 plugin registers its driver and its emulator through the imuhal hooks."""

from __future__ import annotations

from imuhal.plugins.manager import load_registry
from imuhal_chips.ak8963 import plugin


def test_ak8963_plugin_registers_driver_and_emulator_under_one_name() -> None:
    registry = load_registry(entry_point_plugins=False, extra=[("ak8963", plugin)])
    driver = registry.drivers.get("ak8963")
    emulator = registry.emulators.get("ak8963")
    assert driver.name == emulator.chip == "ak8963"
