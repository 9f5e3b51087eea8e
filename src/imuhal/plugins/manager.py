"""Loading plugins from entry points into a Registry.

Allow/block lists: ``IMUHAL_PLUGINS`` (comma-separated entry-point names: load only these) and
``IMUHAL_DISABLE_PLUGINS`` (never load these). Hook implementations with names that match no
hook specification are rejected, so a typo in a plugin fails loudly instead of doing nothing.

Every hook is called once, through pluggy's hook caller (``pm.hook.NAME(register=...)``), so
hook wrappers and tracing see every call. Each registration still records the plugin that
made it, and pluggy says which: before a hook is called, its implementations
(``HookCaller.get_hookimpls()``) give the code of each plugin's function and the name pluggy
knows the plugin by; a registration is attributed to the plugin whose implementation is
running it (the innermost one on the call stack), a wrapper's own registrations included.
The plugin objects are registered as they are, with no stand-in around them.
"""

from __future__ import annotations

import inspect
import os
from collections.abc import Iterable, Mapping
from functools import partial
from importlib.metadata import PackageNotFoundError, entry_points, version
from types import CodeType, ModuleType
from typing import Any

import pluggy

from imuhal.core.errors import PluginError
from imuhal.core.samples import ScalarSample
from imuhal.plugins import hookspecs
from imuhal.plugins.registrars import Registration
from imuhal.plugins.registry import Registry

__all__ = ["ENV_ALLOW", "ENV_BLOCK", "Registry", "load_registry", "plugin_origin"]

ENV_ALLOW = "IMUHAL_PLUGINS"
ENV_BLOCK = "IMUHAL_DISABLE_PLUGINS"


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
    loaded: list[tuple[str, object]] = []

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
            registry.plugins[ep.name] = ep.dist.name if ep.dist is not None else ""
            registry.versions[ep.name] = ep.dist.version if ep.dist is not None else ""
            loaded.append((ep.name, module))
    for name, module in extra:
        if name in block:
            continue
        registry.plugins[name] = ""
        loaded.append((name, module))
    # pluggy calls the last registered implementation first: registering in reverse makes
    # plugins register in load order (sorted entry points, then ``extra``).
    for name, module in reversed(loaded):
        pm.register(module, name=name)

    try:
        pm.check_pending()
    except pluggy.PluginValidationError as exc:
        raise PluginError(f"a plugin implements a hook that does not exist: {exc}") from exc

    for hook_name, registrar in registry.hooks().items():
        caller = getattr(pm.hook, hook_name)
        owners = _owners(caller.get_hookimpls())
        with registry.attributed(partial(_running_plugin, owners)):
            caller(register=registrar)
    _check_emulators(registry)
    _check_quantities(registry)
    return registry


def _owners(impls: Iterable[pluggy.HookImpl]) -> dict[CodeType, str]:
    """The code each hook implementation runs -> the name pluggy registered its plugin
    under (a method's or a decorated function's code is that of what actually runs)."""
    owners: dict[CodeType, str] = {}
    for impl in impls:
        code = getattr(impl.function, "__code__", None)
        if isinstance(code, CodeType):
            owners[code] = impl.plugin_name
    return owners


def _running_plugin(owners: Mapping[CodeType, str]) -> str:
    """The plugin whose hook implementation is running now: the innermost frame on the
    stack that runs the code of one ('' when none does: a registration made by hand)."""
    frame = inspect.currentframe()
    while frame is not None:
        plugin = owners.get(frame.f_code)
        if plugin is not None:
            return plugin
        frame = frame.f_back
    return ""


def plugin_origin(registration: Registration[Any]) -> str:
    """Where a registered class comes from, for one-line messages: its name, the plugin
    (entry point) that registered it, and that plugin's distribution and version when it was
    installed (``plugin 'acme', distribution imuhal-acme 1.0``)."""
    where = f"{registration.name}; plugin {registration.plugin!r}"
    if not registration.package:
        return where  # registered by hand (``load_registry(extra=...)``): no distribution
    try:
        release = version(registration.package)
    except PackageNotFoundError:
        release = "version unknown"
    return f"{where}, distribution {registration.package} {release}"


def _check_emulators(registry: Registry) -> None:
    for name, reg in registry.emulators.entries.items():
        if name not in registry.drivers.entries:
            raise PluginError(
                f"plugin {reg.plugin!r} registered an emulator for {name!r}, "
                f"but no driver of that name is installed"
            )


def _check_quantities(registry: Registry) -> None:
    """A scalar quantity's sample class must carry a scalar. A vector quantity's is a
    VectorSample when its vector is in the chip's frame (calibrated and rotated into the body
    frame by the pipeline), or any Sample that carries a vector in a frame of its own (e.g.
    VelocitySample, NED), which the pipeline passes on unchanged."""
    for name, reg in registry.quantities.entries.items():
        quantity = reg.obj.channel
        if not quantity.is_vector and not issubclass(reg.obj, ScalarSample):
            raise PluginError(
                f"plugin {reg.plugin!r}: quantity {name!r} is a scalar, so its sample class "
                f"{reg.obj.__name__} must subclass ScalarSample")
        if quantity.is_vector and issubclass(reg.obj, ScalarSample):
            raise PluginError(
                f"plugin {reg.plugin!r}: quantity {name!r} has shape {quantity.shape}, so its "
                f"sample class {reg.obj.__name__} must carry a vector (subclass VectorSample "
                "for one in the chip's frame), not subclass ScalarSample")
