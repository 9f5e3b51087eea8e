"""Sinks are plugins: a third party registers one through ``imuhal_register_sinks``."""

from __future__ import annotations

import types
from typing import Any, ClassVar

import pytest

from imuhal.core.errors import PluginError
from imuhal.plugins.hookspecs import hookimpl
from imuhal.plugins.manager import load_registry
from imuhal.sinks.base import Event, SinkPlugin


class CountingSink(SinkPlugin):
    name: ClassVar[str] = "test-counter"
    description: ClassVar[str] = "counts events"

    def __init__(self, settings: Any = None) -> None:
        super().__init__(settings)
        self.events = 0

    def handle(self, event: Event) -> None:
        self.events += 1

    def close(self) -> None:
        pass


def _plugin(cls: type) -> types.ModuleType:
    module = types.ModuleType("sink_plugin")

    @hookimpl
    def imuhal_register_sinks(register: Any) -> None:
        register(cls)

    module.imuhal_register_sinks = imuhal_register_sinks  # type: ignore[attr-defined]
    return module


def test_a_third_party_sink_registers_next_to_the_built_in_ones() -> None:
    registry = load_registry(extra=[("counter", _plugin(CountingSink))])
    assert {"nmea", "vario-audio", "test-counter"} <= set(registry.sinks.names())
    assert registry.sinks.entries["test-counter"].plugin == "counter"
    assert registry.sinks.entries["nmea"].plugin == "sinks"


def test_a_sink_that_is_not_a_sink_plugin_is_refused_naming_the_plugin() -> None:
    class NotASink:
        name = "bogus"

    with pytest.raises(PluginError, match=r"'bad'.*not a subclass of SinkPlugin"):
        load_registry(extra=[("bad", _plugin(NotASink))])
