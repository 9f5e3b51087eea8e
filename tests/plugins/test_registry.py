"""Plugins register through typed registrars; mistakes fail loudly and name the plugin."""

from __future__ import annotations

import types
from dataclasses import dataclass
from typing import ClassVar

import pytest
from tests.support import testchip

from imuhal.cli.main import build_parser
from imuhal.core.errors import PluginError
from imuhal.core.quantities import Quantity
from imuhal.core.samples import AccelSample, ScalarSample
from imuhal.plugins import Command
from imuhal.plugins.hookspecs import hookimpl
from imuhal.plugins.manager import load_registry
from imuhal.sim.errors import SensorErrorSpec


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


def test_hooks_are_called_through_pluggy_so_a_wrapper_sees_every_registration() -> None:
    seen: list[str] = []

    @hookimpl(wrapper=True)
    def imuhal_register_drivers(register):  # type: ignore[no-untyped-def]
        yield
        seen.extend(register.names())

    tracer = _module("tracer", imuhal_register_drivers=imuhal_register_drivers)
    registry = load_registry(entry_point_plugins=False,
                             extra=[("testchip", testchip), ("tracer", tracer)])
    assert seen == ["tc3"]
    assert registry.drivers.entries["tc3"].plugin == "testchip"  # still attributed


def test_a_quantity_whose_sample_class_has_the_wrong_shape_is_rejected() -> None:
    @dataclass(frozen=True, slots=True, kw_only=True)
    class WindSample(ScalarSample):
        channel: ClassVar[Quantity] = Quantity("wind", "m/s", (3,))

    @hookimpl
    def imuhal_register_quantities(register):  # type: ignore[no-untyped-def]
        register(WindSample)

    bad = _module("bad", imuhal_register_quantities=imuhal_register_quantities)
    with pytest.raises(PluginError, match=r"plugin 'bad'.*'wind'.*must carry a vector"):
        load_registry(entry_point_plugins=False, extra=[("bad", bad)])


def test_a_plugin_cannot_take_over_a_built_in_quantity() -> None:
    @hookimpl
    def imuhal_register_quantities(register):  # type: ignore[no-untyped-def]
        register(AccelSample)

    again = _module("again", imuhal_register_quantities=imuhal_register_quantities)
    with pytest.raises(PluginError, match=r"quantity 'accel' registered twice.*'imuhal'"):
        load_registry(entry_point_plugins=False, extra=[("again", again)])


def test_a_plugin_command_named_like_a_built_in_one_is_refused() -> None:
    class Run(Command):
        name = "run"

        def run(self, args, registry):  # type: ignore[no-untyped-def]
            return 0

    @hookimpl
    def imuhal_register_commands(register):  # type: ignore[no-untyped-def]
        register(Run)

    clash = _module("clash", imuhal_register_commands=imuhal_register_commands)
    registry = load_registry(entry_point_plugins=False, extra=[("clash", clash)])
    with pytest.raises(PluginError, match=r"plugin 'clash'.*'run'.*must rename"):
        build_parser(registry)


def test_an_emulator_error_spec_is_typed_and_a_typo_fails_when_the_class_is_defined() -> None:
    class Good(testchip.TC3Emulator):
        error_spec = {"accel": {"noise_std": 0.01}}  # type: ignore[assignment]  # noqa: RUF012

    assert isinstance(Good.error_spec, SensorErrorSpec)
    assert Good.error_spec.accel is not None and Good.error_spec.accel.noise_std == 0.01
    with pytest.raises(TypeError, match=r"Typo.error_spec is not a valid SensorErrorSpec"):
        class Typo(testchip.TC3Emulator):
            error_spec = {"accel": {"noise_stdev": 0.01}}  # type: ignore[assignment]  # noqa: RUF012


def test_each_registration_is_attributed_to_the_plugin_whose_hook_made_it() -> None:
    """pluggy calls both implementations in one hook call; each registration still names the
    plugin that made it, also when it is made through a helper of that plugin."""
    @dataclass(frozen=True, slots=True, kw_only=True)
    class HumiditySample(ScalarSample):
        channel: ClassVar[Quantity] = Quantity("humidity", "%RH", ())

    def register_through_a_helper(register):  # type: ignore[no-untyped-def]
        register(HumiditySample)

    @hookimpl
    def imuhal_register_quantities(register):  # type: ignore[no-untyped-def]
        register_through_a_helper(register)

    class Plugin:  # a plugin object whose hook implementation is a method
        @hookimpl
        def imuhal_register_drivers(self, register):  # type: ignore[no-untyped-def]
            register(testchip.TC3Driver)

    humid = _module("humid", imuhal_register_quantities=imuhal_register_quantities)
    registry = load_registry(entry_point_plugins=False,
                             extra=[("humid", humid), ("chips", Plugin())])
    assert registry.quantities.entries["humidity"].plugin == "humid"
    assert registry.drivers.entries["tc3"].plugin == "chips"
    assert registry.quantities.entries["accel"].plugin == "imuhal"


def test_the_entry_point_plugins_name_their_distribution_and_its_version() -> None:
    from importlib.metadata import version

    registry = load_registry()
    assert registry.drivers.entries["ms5611"].plugin == "ms5611"
    assert registry.drivers.entries["ms5611"].package == "imuhal"
    assert registry.versions["ms5611"] == version("imuhal")
