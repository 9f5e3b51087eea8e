"""Plugins register through typed registrars; mistakes fail loudly and name the plugin."""

from __future__ import annotations

import types

import pytest
from tests.support import testchip

from imuhal.core.errors import PluginError
from imuhal.plugins.hookspecs import hookimpl
from imuhal.plugins.manager import load_registry


def _module(name: str, **attrs: object) -> types.ModuleType:
    mod = types.ModuleType(name)
    for key, value in attrs.items():
        setattr(mod, key, value)
    return mod


def test_built_in_bus_kinds_and_scenarios_come_from_entry_points() -> None:
    registry = load_registry()
    assert {"i2c", "spi", "serial"} <= set(registry.buses.names())
    assert "thermal" in registry.scenarios.names()
    assert registry.buses.entries["i2c"].package == "imuhal"


def test_a_plugin_registers_its_driver_and_emulator() -> None:
    registry = load_registry(entry_point_plugins=False, extra=[("testchip", testchip)])
    assert registry.drivers.get("tc3") is testchip.TC3Driver
    assert registry.emulators.entries["tc3"].plugin == "testchip"


def test_a_misspelt_hook_is_rejected() -> None:
    @hookimpl
    def imuhal_register_driver(register):  # type: ignore[no-untyped-def]  # missing "s"
        pass

    bad = _module("bad", imuhal_register_driver=imuhal_register_driver)
    with pytest.raises(PluginError, match="hook that does not exist"):
        load_registry(entry_point_plugins=False, extra=[("bad", bad)])


def test_registering_something_that_is_not_a_driver_names_the_plugin() -> None:
    @hookimpl
    def imuhal_register_drivers(register):  # type: ignore[no-untyped-def]
        register(int)

    bad = _module("bad", imuhal_register_drivers=imuhal_register_drivers)
    with pytest.raises(PluginError, match=r"plugin 'bad'.*not a subclass of Driver"):
        load_registry(entry_point_plugins=False, extra=[("bad", bad)])


def test_the_same_name_twice_is_an_error_naming_both_plugins() -> None:
    @hookimpl
    def imuhal_register_drivers(register):  # type: ignore[no-untyped-def]
        register(testchip.TC3Driver)

    twin = _module("twin", imuhal_register_drivers=imuhal_register_drivers)
    with pytest.raises(PluginError, match=r"registered twice.*'testchip'.*'twin'"):
        load_registry(entry_point_plugins=False, extra=[("testchip", testchip), ("twin", twin)])


def test_an_emulator_without_its_driver_is_rejected() -> None:
    @hookimpl
    def imuhal_register_emulators(register):  # type: ignore[no-untyped-def]
        register(testchip.TC3Emulator)

    orphan = _module("orphan", imuhal_register_emulators=imuhal_register_emulators)
    with pytest.raises(PluginError, match="no driver of that name"):
        load_registry(entry_point_plugins=False, extra=[("orphan", orphan)])


def test_unknown_names_list_what_is_installed() -> None:
    registry = load_registry(entry_point_plugins=False, extra=[("testchip", testchip)])
    with pytest.raises(PluginError, match=r"no driver named 'nope'.*installed: tc3"):
        registry.drivers.get("nope")


def test_block_list_skips_an_entry_point(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("IMUHAL_DISABLE_PLUGINS", "scenarios")
    registry = load_registry()
    assert "scenarios" not in registry.plugins
    assert "thermal" not in registry.scenarios.names()


def test_allow_list_loads_only_the_named_entry_points(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("IMUHAL_PLUGINS", "buses")
    registry = load_registry()
    assert set(registry.plugins) == {"buses"}
