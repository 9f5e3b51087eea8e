"""Loading plugins from entry points into a Registry.

Allow/block lists: ``IMUHAL_PLUGINS`` (comma-separated entry-point names: load only these) and
``IMUHAL_DISABLE_PLUGINS`` (never load these). Hook implementations with names that match no
hook specification are rejected, so a typo in a plugin fails loudly instead of doing nothing.
"""

from __future__ import annotations

import os
from collections.abc import Iterable
from dataclasses import dataclass, field
from importlib.metadata import entry_points
from types import ModuleType
from typing import Any

import pluggy

from imuhal.bus.factory import BusFactory
from imuhal.core.errors import PluginError
from imuhal.drivers.base import Driver
from imuhal.estimation.base import Estimator
from imuhal.plugins import hookspecs
from imuhal.plugins.registrars import Registrar
from imuhal.sim.chip import ChipEmulator
from imuhal.sim.scenario import Scenario
from imuhal.sinks.base import SinkPlugin

ENV_ALLOW = "IMUHAL_PLUGINS"
ENV_BLOCK = "IMUHAL_DISABLE_PLUGINS"


@dataclass
class Registry:
    """Everything the installed plugins registered."""

    drivers: Registrar[Driver] = field(default_factory=lambda: Registrar("driver", Driver))
    emulators: Registrar[ChipEmulator] = field(
        default_factory=lambda: Registrar("emulator", ChipEmulator, name_attr="chip")
    )
    estimators: Registrar[Estimator] = field(
        default_factory=lambda: Registrar("estimator", Estimator)
    )
    buses: Registrar[BusFactory] = field(
        default_factory=lambda: Registrar("bus kind", BusFactory, name_attr="scheme")
    )
    scenarios: Registrar[Scenario] = field(
        default_factory=lambda: Registrar("scenario", Scenario)
    )
    sinks: Registrar[SinkPlugin] = field(default_factory=lambda: Registrar("sink", SinkPlugin))
    plugins: dict[str, str] = field(default_factory=dict)
    """Loaded plugin name -> distribution name."""

    def registrar_for(self, hook: str) -> Registrar[Any]:
        return {
            "imuhal_register_drivers": self.drivers,
            "imuhal_register_emulators": self.emulators,
            "imuhal_register_estimators": self.estimators,
            "imuhal_register_buses": self.buses,
            "imuhal_register_scenarios": self.scenarios,
            "imuhal_register_sinks": self.sinks,
        }[hook]


def _split_env(name: str) -> set[str] | None:
    raw = os.environ.get(name, "").strip()
    if not raw:
        return None
    return {part.strip() for part in raw.split(",") if part.strip()}


def _plugin_manager() -> pluggy.PluginManager:
    pm = pluggy.PluginManager(hookspecs.PROJECT)
    pm.add_hookspecs(hookspecs)
    return pm


def load_registry(
    *,
    entry_point_plugins: bool = True,
    extra: Iterable[tuple[str, ModuleType | object]] = (),
) -> Registry:
    """Load plugins (entry points, then ``extra`` (name, module) pairs) into a new Registry."""
    pm = _plugin_manager()
    registry = Registry()
    allow = _split_env(ENV_ALLOW)
    block = _split_env(ENV_BLOCK) or set()

    if entry_point_plugins:
        for ep in sorted(entry_points(group=hookspecs.ENTRY_POINT_GROUP), key=lambda e: e.name):
            if ep.name in block or (allow is not None and ep.name not in allow):
                continue
            try:
                module = ep.load()
            except Exception as exc:  # a broken plugin must name itself, not crash obscurely
                raise PluginError(
                    f"plugin {ep.name!r} ({ep.value}) failed to load: "
                    f"{type(exc).__name__}: {exc}; set {ENV_BLOCK}={ep.name} to skip it"
                ) from exc
            dist = ep.dist.name if ep.dist is not None else ""
            pm.register(module, name=ep.name)
            registry.plugins[ep.name] = dist
    for name, module in extra:
        if name in block:
            continue
        pm.register(module, name=name)
        registry.plugins[name] = ""

    try:
        pm.check_pending()
    except pluggy.PluginValidationError as exc:
        raise PluginError(f"a plugin implements a hook that does not exist: {exc}") from exc

    for hook_name in (
        "imuhal_register_buses",
        "imuhal_register_drivers",
        "imuhal_register_emulators",
        "imuhal_register_estimators",
        "imuhal_register_scenarios",
        "imuhal_register_sinks",
    ):
        registrar = registry.registrar_for(hook_name)
        caller = getattr(pm.hook, hook_name)
        # Called one implementation at a time so each registration records its plugin.
        for impl in caller.get_hookimpls():
            plugin_name = impl.plugin_name
            registrar._bind(plugin_name, registry.plugins.get(plugin_name, ""))
            impl.function(register=registrar)
        registrar._bind("", "")
    _check_emulators(registry)
    return registry


def _check_emulators(registry: Registry) -> None:
    for name, reg in registry.emulators.entries.items():
        if name not in registry.drivers.entries:
            raise PluginError(
                f"plugin {reg.plugin!r} registered an emulator for {name!r}, "
                f"but no driver of that name is installed"
            )
