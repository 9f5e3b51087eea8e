"""Loading and checking board profiles, reporting every problem at once with its location.

Two passes: the board schema (profile/model.py), then each bus, device and estimator against
the Settings model of the plugin it names. Both passes collect problems instead of stopping at
the first, and each problem reads ``file:line:column: path: what is wrong (value); allowed``.
"""

from __future__ import annotations

import types
import typing
from pathlib import Path as FsPath
from typing import Any

import yaml
from pydantic import BaseModel, ValidationError

from imuhal.bus.base import BusKind
from imuhal.core.errors import ProfileError
from imuhal.plugins.manager import Registry
from imuhal.profile.faults import CHIP_FAULT_KINDS, FAULT_KINDS
from imuhal.profile.model import SCHEMA_VERSION, BoardProfile
from imuhal.profile.yaml_source import LocatedDocument, Path, dotted, load_located

_FAULT_TAGS = frozenset(k.model_fields["kind"].default for k in FAULT_KINDS)


def load_profile(path: str | FsPath, registry: Registry | None = None) -> BoardProfile:
    """Load and fully validate a profile; raise ProfileError listing every problem."""
    text, source = _read(path)
    return parse_profile(text, source, registry)


def parse_profile(text: str, source: str, registry: Registry | None = None) -> BoardProfile:
    problems, profile = _check(text, source, registry)
    if problems or profile is None:
        raise ProfileError(source, problems)
    return profile


def check_profile(path: str | FsPath, registry: Registry | None = None) -> list[str]:
    """Every problem in the profile at ``path`` (empty when it is valid)."""
    try:
        text, source = _read(path)
    except ProfileError as exc:
        return exc.problems
    return _check(text, source, registry)[0]


def _read(path: str | FsPath) -> tuple[str, str]:
    p = FsPath(path)
    try:
        return p.read_text(encoding="utf-8"), str(p)
    except FileNotFoundError:
        raise ProfileError(str(p), ["file not found; give the path of a .yaml profile "
                                    "(see profiles/ for examples)"]) from None
    except (OSError, UnicodeDecodeError) as exc:
        raise ProfileError(str(p), [f"cannot read: {exc}"]) from None


def _check(
    text: str, source: str, registry: Registry | None
) -> tuple[list[str], BoardProfile | None]:
    try:
        doc = load_located(text, source)
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        where = f"{source}:{mark.line + 1}:{mark.column + 1}" if mark else source
        problem = getattr(exc, "problem", None) or str(exc)
        label = "not allowed" if isinstance(exc, yaml.constructor.ConstructorError) \
            else "YAML syntax error"
        return [f"{where}: {label}: {problem}"], None
    problems = list(doc.problems)
    if not isinstance(doc.data, dict):
        return [*problems, f"{source}:1:1: a profile is a YAML mapping with schema_version, "
                f"name, buses and devices"], None
    version = doc.data.get("schema_version")
    if version is not None and version != SCHEMA_VERSION:
        problems.append(
            f"{doc.where(('schema_version',))}: schema_version: {version!r} is not supported; "
            f"this imuhal reads schema_version {SCHEMA_VERSION}"
        )
        return problems, None
    try:
        profile = BoardProfile.model_validate(doc.data)
    except ValidationError as exc:
        problems += _describe(exc, doc, (), BoardProfile)
        return problems, None
    problems += _check_references(profile, doc)
    if registry is not None:
        problems += _check_plugins(profile, doc, registry)
    return problems, (profile if not problems else None)


def _describe(exc: ValidationError, doc: LocatedDocument, prefix: Path,
              model: type[BaseModel]) -> list[str]:
    out = []
    for err in exc.errors(include_url=False):
        loc = _clean_loc(err["loc"])
        path = (*prefix, *loc)
        kind = err["type"]
        where = doc.where(path, key=kind in ("extra_forbidden", "missing"))
        if kind == "extra_forbidden":
            allowed = _allowed_keys(model, loc[:-1])
            hint = f"; allowed keys: {', '.join(allowed)}" if allowed else ""
            out.append(f"{where}: {dotted(path)}: unknown key{hint}")
        elif kind == "missing":
            out.append(f"{where}: {dotted(path)}: required key is missing; add it")
        else:
            value = err.get("input")
            msg = err["msg"]
            if isinstance(err.get("ctx"), dict) and "error" in err["ctx"]:
                msg = str(err["ctx"]["error"])
            out.append(f"{where}: {dotted(path)}: {msg} (found {value!r})")
    return out


def _validate(model: type[BaseModel], data: Any, doc: LocatedDocument, path: Path) -> list[str]:
    """A plugin's settings checked by its own model: located problems, or none."""
    try:
        model.model_validate(data)
    except ValidationError as exc:
        return _describe(exc, doc, path, model)
    return []


def _clean_loc(loc: tuple[Any, ...]) -> Path:
    # pydantic inserts union-branch tags such as 'str' or 'list[list[float]]' into loc, and
    # the ``kind`` of a tagged union member (a fault) after its list index
    out: list[Any] = []
    for p in loc:
        if isinstance(p, str) and ("[" in p or p in {"str"}):
            continue
        if isinstance(p, str) and out and isinstance(out[-1], int) and p in _FAULT_TAGS:
            continue
        out.append(p)
    return tuple(out)


def _allowed_keys(model: type[BaseModel], loc: Path) -> list[str]:
    target: Any = model
    for part in loc:
        if isinstance(target, type) and issubclass(target, BaseModel):
            field = target.model_fields.get(str(part))
            if field is None:
                return []
            target = _unwrap(field.annotation)
        elif typing.get_origin(target) is dict:
            target = _unwrap(typing.get_args(target)[1])
        else:
            return []
    if isinstance(target, type) and issubclass(target, BaseModel):
        return list(target.model_fields)
    return []


def _unwrap(annotation: Any) -> Any:
    origin = typing.get_origin(annotation)
    if origin in (typing.Union, types.UnionType):
        args = [a for a in typing.get_args(annotation) if a is not type(None)]
        models = [a for a in args if isinstance(a, type) and issubclass(a, BaseModel)]
        return models[0] if models else (args[0] if args else annotation)
    return annotation


def _check_references(profile: BoardProfile, doc: LocatedDocument) -> list[str]:
    out = []
    device_names = set(profile.devices)
    for name, dev in profile.devices.items():
        path: Path = ("devices", name, "bus")
        if "/" in dev.bus:
            parent = dev.bus.split("/", 1)[0]
            if parent not in device_names:
                names = ", ".join(sorted(device_names))
                out.append(f"{doc.where(path)}: {dotted(path)}: {dev.bus!r} names device "
                           f"{parent!r}, which is not in devices ({names})")
            elif parent == name:
                out.append(f"{doc.where(path)}: {dotted(path)}: a device cannot sit on its own bus")
        elif dev.bus not in profile.buses:
            out.append(f"{doc.where(path)}: {dotted(path)}: no bus named {dev.bus!r}; "
                       f"defined buses: {', '.join(sorted(profile.buses)) or 'none'}")
    known = device_names | set(profile.estimators)
    for name, est in profile.estimators.items():
        for i, ref in enumerate(est.inputs or []):
            if ref not in known:
                path = ("estimators", name, "inputs", i)
                out.append(f"{doc.where(path)}: {dotted(path)}: {ref!r} is neither a device nor "
                           f"an estimator of this profile")
    enabled = sorted(n for n, d in profile.devices.items() if d.enabled)
    for i, fault in enumerate(profile.emulation.faults):
        if fault.device not in enabled:
            path = ("emulation", "faults", i, "device")
            out.append(f"{doc.where(path)}: {dotted(path)}: {fault.device!r} is not an enabled "
                       f"device of this profile; devices: {', '.join(enabled) or 'none'}")
    return out


def _check_plugins(profile: BoardProfile, doc: LocatedDocument, registry: Registry) -> list[str]:
    out: list[str] = []
    bus_kinds: dict[str, BusKind | None] = {}
    for name, bus in profile.buses.items():
        path: Path = ("buses", name)
        factory = registry.buses.entries.get(bus.kind)
        if factory is None:
            out.append(f"{doc.where((*path, 'kind'))}: {dotted((*path, 'kind'))}: unknown bus kind "
                       f"{bus.kind!r}; installed: {', '.join(registry.buses.names())}")
            bus_kinds[name] = None
            continue
        bus_kinds[name] = factory.obj.kind
        out += _validate(factory.obj.Settings, bus.plugin_settings(), doc, path)
    for name, dev in profile.devices.items():
        path = ("devices", name)
        reg = registry.drivers.entries.get(dev.driver)
        if reg is None:
            out.append(f"{doc.where((*path, 'driver'))}: {dotted((*path, 'driver'))}: no driver "
                       f"named {dev.driver!r} is installed; installed: "
                       f"{', '.join(registry.drivers.names()) or 'none'} (see `imuhal plugins`)")
            continue
        driver = reg.obj
        kind = bus_kinds.get(dev.bus) if "/" not in dev.bus else BusKind.I2C
        if kind is not None and kind not in driver.bus_kinds:
            allowed = ", ".join(sorted(k.value for k in driver.bus_kinds))
            out.append(f"{doc.where((*path, 'bus'))}: {dotted((*path, 'bus'))}: {dev.driver} "
                       f"cannot sit on a {kind.value} bus; it supports: {allowed}")
        out += _validate(driver.Settings, dev.settings, doc, (*path, "settings"))
    for name, est in profile.estimators.items():
        path = ("estimators", name)
        reg_e = registry.estimators.entries.get(est.estimator)
        if reg_e is None:
            out.append(f"{doc.where((*path, 'estimator'))}: {dotted((*path, 'estimator'))}: no "
                       f"estimator named {est.estimator!r} is installed; installed: "
                       f"{', '.join(registry.estimators.names()) or 'none'}")
            continue
        out += _validate(reg_e.obj.Settings, est.settings, doc, (*path, "settings"))
    out += _check_fault_support(profile, doc, registry)
    scenario = profile.emulation.scenario
    if registry.scenarios.entries and scenario not in registry.scenarios.entries:
        p: Path = ("emulation", "scenario")
        out.append(f"{doc.where(p)}: {dotted(p)}: unknown scenario {scenario!r}; installed: "
                   f"{', '.join(registry.scenarios.names())}")
    return out


def _check_fault_support(profile: BoardProfile, doc: LocatedDocument,
                         registry: Registry) -> list[str]:
    """Chip-level faults need an emulator that models them (ChipEmulator.chip_faults)."""
    out = []
    for i, fault in enumerate(profile.emulation.faults):
        dev = profile.devices.get(fault.device)
        if fault.kind not in CHIP_FAULT_KINDS or dev is None:
            continue
        reg = registry.emulators.entries.get(dev.driver)
        if reg is None:
            continue  # running emulated reports the missing emulator itself
        supported = reg.obj.chip_faults()
        if fault.kind not in supported:
            path: Path = ("emulation", "faults", i, "kind")
            out.append(f"{doc.where(path)}: {dotted(path)}: the {dev.driver} emulator does not "
                       f"model {fault.kind!r}; it models: {', '.join(sorted(supported))}")
    return out
