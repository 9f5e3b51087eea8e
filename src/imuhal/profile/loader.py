"""Loading and checking board profiles, reporting every problem at once with its location.

Every check runs on every profile and all problems go into one report, each reading
``file:line:column: path: what is wrong (value); allowed``: the board schema
(profile/model.py), references between buses and devices, unique (bus, address) pairs, and
each bus, device and estimator against the Settings model of the plugin it names. An
unsupported ``schema_version`` is one more problem, not the only one.

Numbers are strict: ``true`` is not a number and neither is ``"5"`` (an integer is a valid
float). Input is bounded: at most ``MAX_PROFILE_BYTES``
bytes, and a bounded alias expansion (profile/yaml_source.py).
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
from imuhal.core.samples import VectorSample
from imuhal.drivers.settings import BUS_CONTEXT, BUS_FEATURES_CONTEXT
from imuhal.plugins.manager import Registry
from imuhal.profile.faults import CHIP_FAULT_KINDS, FAULT_KINDS
from imuhal.profile.model import MOVED_SECTIONS, SCHEMA_VERSION, BoardProfile, OutputsConfig
from imuhal.profile.yaml_source import (
    ExpansionError,
    LocatedDocument,
    Path,
    dotted,
    load_located,
)

MAX_PROFILE_BYTES = 1_000_000
"""Largest profile file read (1 MB); a board profile is a few kB."""

_FAULT_TAGS = frozenset(k.model_fields["kind"].default for k in FAULT_KINDS)


def load_profile(path: str | FsPath, registry: Registry | None = None) -> BoardProfile:
    """Load and fully validate a profile; raise ProfileError listing every problem."""
    return parse_profile(read_profile_text(path), str(path), registry)


def parse_profile(text: str, source: str, registry: Registry | None = None) -> BoardProfile:
    problems, profile = _check(text, source, registry)
    if problems or profile is None:
        raise ProfileError(source, problems)
    return profile


def check_profile(path: str | FsPath, registry: Registry | None = None) -> list[str]:
    """Every problem in the profile at ``path`` (empty when it is valid)."""
    try:
        text = read_profile_text(path)
    except ProfileError as exc:
        return exc.problems
    return _check(text, str(path), registry)[0]


def read_profile_text(path: str | FsPath) -> str:
    """The text of the profile at ``path``: at most MAX_PROFILE_BYTES of UTF-8, or a
    ProfileError saying what is wrong with the file."""
    p = FsPath(path)
    try:
        # Opening a FIFO would wait for a writer for ever, and a device never ends.
        if p.exists() and not p.is_dir() and not p.is_file():
            raise ProfileError(str(p), ["is not a regular file (a FIFO, socket or device); "
                                        "give the path of a .yaml profile"])
        with p.open("rb") as f:
            data = f.read(MAX_PROFILE_BYTES + 1)
    except FileNotFoundError:
        raise ProfileError(str(p), ["file not found; give the path of a .yaml profile "
                                    "(see profiles/ for examples)"]) from None
    except IsADirectoryError:
        raise ProfileError(str(p), ["is a directory; give the path of a .yaml profile"]) from None
    except OSError as exc:
        raise ProfileError(str(p), [f"cannot read: {exc.strerror or exc}"]) from None
    if len(data) > MAX_PROFILE_BYTES:
        raise ProfileError(str(p), [f"the file is larger than {MAX_PROFILE_BYTES / 1e6:g} MB; a "
                                    "board profile is a few kB - is this the right file?"])
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise ProfileError(str(p), [f"not UTF-8 text (byte {exc.start}); save the profile as "
                                    "UTF-8"]) from None


def _check(
    text: str, source: str, registry: Registry | None
) -> tuple[list[str], BoardProfile | None]:
    try:
        doc = load_located(text, source)
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        where = f"{source}:{mark.line + 1}:{mark.column + 1}" if mark else source
        problem = getattr(exc, "problem", None) or str(exc)
        refused = isinstance(exc, yaml.constructor.ConstructorError | ExpansionError)
        label = "not allowed" if refused else "YAML syntax error"
        return [f"{where}: {label}: {problem}"], None
    problems = list(doc.problems)
    if not isinstance(doc.data, dict):
        return [*problems, f"{source}:1:1: a profile is a YAML mapping with schema_version, "
                f"name, buses and devices"], None
    data = doc.data
    version = data.get("schema_version", SCHEMA_VERSION)
    if type(version) is not int or version != SCHEMA_VERSION:
        problems.append(
            f"{doc.where(('schema_version',))}: schema_version: {version!r} is not supported; "
            f"this imuhal reads schema_version {SCHEMA_VERSION}"
        )
        # Checked as if it were right, so that every other problem is reported too.
        data = {**data, "schema_version": SCHEMA_VERSION}
    moved = _moved_sections(data, doc)
    problems += moved
    if moved:  # reported once, as moved, not again as unknown keys
        data = {k: v for k, v in data.items() if k not in MOVED_SECTIONS}
    profile = None
    try:
        profile = validate_strict(BoardProfile, data)
    except ValidationError as exc:
        problems += _describe(exc, doc, (), BoardProfile)
    problems += _check_references(data, doc)
    if registry is not None:
        problems += _check_plugins(data, doc, registry)
        if profile is not None:
            problems += _check_fault_support(profile, doc, registry)
    return problems, (profile if not problems else None)


def _moved_sections(data: dict[str, Any], doc: LocatedDocument) -> list[str]:
    """One line for each top-level output section of earlier profiles (``ros:``, ``igc:``,
    ``mavlink:``), naming its place under ``outputs``."""
    return [f"{doc.where((key,), key=True)}: {key}: moved under outputs: write "
            f"`outputs: {{{new}: ...}}` with the same keys (docs/profiles.md)"
            for key, new in MOVED_SECTIONS.items() if key in data]


def validate_strict(model: type[BaseModel], data: Any,
                    context: dict[str, Any] | None = None) -> Any:
    """``model`` validated from ``data``, with numbers strict: pydantic turns ``true`` into 1
    and ``"500"`` into 500, which a profile must not (``rate_hz: true`` is an error, not
    1 Hz). YAML lists are still fine for tuples and strings for choices and dates.

    Validation is pydantic's own (so models' validators run as written); afterwards every
    bool or string of ``data`` that came out as a number is an error at its path.
    """
    result = model.model_validate(data, context=context)
    coerced = [{"type": "float_type", "loc": path, "input": value}
               for path, value in _coerced_numbers(data, result, ())]
    if coerced:
        raise ValidationError.from_exception_data(model.__name__, coerced)  # type: ignore[arg-type]  # pydantic's error-details TypedDict: a float_type error needs only these keys
    return result


_MISSING = object()


def _coerced_numbers(given: Any, made: Any, path: Path) -> typing.Iterator[tuple[Path, Any]]:
    """(path, value) of each bool or string in ``given`` whose validated value in ``made``
    is a number."""
    if isinstance(given, bool | str):
        if isinstance(made, int | float) and not isinstance(made, bool):
            yield path, given
        return
    items = given.items() if isinstance(given, dict) else (
        enumerate(given) if isinstance(given, list) else ())
    for key, value in items:
        child = _child(made, key)
        if child is not _MISSING:
            yield from _coerced_numbers(value, child, (*path, key))


def _child(made: Any, key: Any) -> Any:
    if isinstance(made, BaseModel):
        if isinstance(key, str) and key in type(made).model_fields:
            return getattr(made, key)
        return (made.model_extra or {}).get(key, _MISSING)
    if isinstance(made, dict):
        return made.get(key, _MISSING)
    if isinstance(made, list | tuple) and isinstance(key, int) and 0 <= key < len(made):
        return made[key]
    return _MISSING


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


def _validate(model: type[BaseModel], data: Any, doc: LocatedDocument, path: Path,
              context: dict[str, Any] | None = None) -> list[str]:
    """A plugin's settings checked by its own model (with ``context`` for its validators):
    located problems, or none."""
    try:
        validate_strict(model, data, context)
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


def _mapping(value: Any) -> dict[Any, Any]:
    return value if isinstance(value, dict) else {}


def _text(value: Any) -> str | None:
    return value if isinstance(value, str) else None


def _check_references(data: dict[str, Any], doc: LocatedDocument) -> list[str]:
    """Buses, parent devices and estimator inputs that do not exist, and two enabled devices
    at one (bus, address), checked on the raw document so that they are reported even when
    other parts of the profile are malformed."""
    buses = _mapping(data.get("buses"))
    devices = {n: d for n, d in _mapping(data.get("devices")).items() if isinstance(d, dict)}
    out = []
    taken: dict[tuple[str, int], str] = {}
    for name, dev in devices.items():
        bus = _text(dev.get("bus"))
        if bus is not None:
            out += _check_device_bus(name, bus, buses, set(devices), doc)
            out += _check_address(name, dev, bus, buses, taken, doc)
    out += _check_estimator_inputs(data, set(devices), doc)
    out += _check_fault_devices(data, devices, doc)
    return out


def _check_device_bus(name: Any, bus: str, buses: dict[Any, Any], device_names: set[Any],
                      doc: LocatedDocument) -> list[str]:
    """A device's bus: a profile bus, or ``DEVICE/CHILD`` of another device."""
    path: Path = ("devices", name, "bus")
    if "/" not in bus:
        return [] if bus in buses else [
            f"{doc.where(path)}: {dotted(path)}: no bus named {bus!r}; "
            f"defined buses: {', '.join(sorted(map(str, buses))) or 'none'}"]
    parent = bus.split("/", 1)[0]
    if parent not in device_names:
        names = ", ".join(sorted(map(str, device_names)))
        return [f"{doc.where(path)}: {dotted(path)}: {bus!r} names device "
                f"{parent!r}, which is not in devices ({names})"]
    if parent == name:
        return [f"{doc.where(path)}: {dotted(path)}: a device cannot sit on its own bus"]
    return []


def _check_address(name: Any, dev: dict[Any, Any], bus: str, buses: dict[Any, Any],
                   taken: dict[tuple[str, int], str], doc: LocatedDocument) -> list[str]:
    """Two enabled chips at one address of one bus (``taken``: the first at each)."""
    address = dev.get("address")
    # Addresses name a chip on I2C and SPI (and behind a chip's I2C master); other bus
    # kinds (serial, iio) find their device otherwise and may leave the address at 0.
    kind = "i2c" if "/" in bus else _text(_mapping(buses.get(bus)).get("kind"))
    if type(address) is not int or kind not in ("i2c", "spi") or \
            dev.get("enabled", True) is False:
        return []
    other = taken.setdefault((bus, address), str(name))
    if other == name:
        return []
    apath: Path = ("devices", name, "address")
    return [f"{doc.where(apath)}: {dotted(apath)}: 0x{address:02X} on bus {bus!r} "
            f"is already taken by devices.{other} "
            f"({doc.where(('devices', other, 'address'))}); two chips cannot "
            "answer at one address - fix the address or disable one device"]


def _check_estimator_inputs(data: dict[str, Any], device_names: set[Any],
                            doc: LocatedDocument) -> list[str]:
    """Each estimator input names a device or another estimator."""
    estimators = {n: e for n, e in _mapping(data.get("estimators")).items()
                  if isinstance(e, dict)}
    known = device_names | set(estimators)
    out = []
    for name, est in estimators.items():
        inputs = est.get("inputs")
        for i, ref in enumerate(inputs if isinstance(inputs, list) else []):
            if isinstance(ref, str) and ref not in known:
                path: Path = ("estimators", name, "inputs", i)
                out.append(f"{doc.where(path)}: {dotted(path)}: {ref!r} is neither a device nor "
                           f"an estimator of this profile")
    return out


def _check_fault_devices(data: dict[str, Any], devices: dict[Any, Any],
                         doc: LocatedDocument) -> list[str]:
    """Each emulated fault names an enabled device."""
    enabled = sorted(str(n) for n, d in devices.items() if d.get("enabled", True) is not False)
    faults = _mapping(data.get("emulation")).get("faults")
    out = []
    for i, fault in enumerate(faults if isinstance(faults, list) else []):
        device = _text(fault.get("device")) if isinstance(fault, dict) else None
        if device is not None and device not in enabled:
            path: Path = ("emulation", "faults", i, "device")
            out.append(f"{doc.where(path)}: {dotted(path)}: {device!r} is not an enabled "
                       f"device of this profile; devices: {', '.join(enabled) or 'none'}")
    return out


def _calibration_keys(calibration: Any) -> list[str]:
    """The quantity names a device's raw ``calibration`` mapping holds records for (the keys
    that are not settings of the calibration itself)."""
    return [k for k in _mapping(calibration) if isinstance(k, str)
            and k not in ("gyro_at_startup", "mag_in_flight", "accel_in_flight",
                                         "previous")]


def _calibratable(quantity: str, registry: Registry) -> bool:
    """Whether ``quantity`` is a vector in the chip's frame (a VectorSample): what a
    calibration record corrects."""
    reg = registry.quantities.entries.get(quantity)
    return reg is not None and issubclass(reg.obj, VectorSample)


def _bus_kind(devices: dict[Any, Any], ref: str, bus_kinds: dict[str, BusKind | None],
              registry: Registry) -> tuple[BusKind | None, str]:
    """The kind of bus ``ref`` (a profile bus, or ``DEVICE/CHILD``: a bus a chip provides, of
    the kind its driver declares), or None when unknown; and a problem to report, if any."""
    if "/" not in ref:
        return bus_kinds.get(ref), ""
    parent, child = ref.split("/", 1)
    parent_driver = _text(_mapping(devices.get(parent)).get("driver"))
    reg = registry.drivers.entries.get(parent_driver) if parent_driver is not None else None
    if reg is None:
        return None, ""  # the topology check names a missing parent device
    provided = reg.obj.child_bus_kinds
    if child not in provided:
        return None, (f"device {parent!r} ({parent_driver}) provides no bus {child!r}; it "
                      f"provides: {', '.join(provided) or 'none'}")
    return provided[child], ""


def _bus_features(devices: dict[Any, Any], ref: str, registry: Registry) -> frozenset[str]:
    """What the bus ``ref`` offers beyond transfers: a child bus what its parent's driver
    declares for it with the parent's settings (``Driver.child_bus_features_with``); a bus
    the profile opens itself, nothing."""
    if "/" not in ref:
        return frozenset()
    parent, child = ref.split("/", 1)
    parent_device = _mapping(devices.get(parent))
    parent_driver = _text(parent_device.get("driver"))
    reg = registry.drivers.entries.get(parent_driver) if parent_driver is not None else None
    if reg is None:
        return frozenset()
    return reg.obj.child_bus_features_with(child, _mapping(parent_device.get("settings")))


def _check_plugins(data: dict[str, Any], doc: LocatedDocument, registry: Registry) -> list[str]:
    """Each bus, device and estimator against its plugin's Settings model (on the raw
    document, skipping parts too malformed to tell which plugin they name)."""
    out: list[str] = []
    bus_kinds: dict[str, BusKind | None] = {}
    for name, bus in _mapping(data.get("buses")).items():
        out += _check_bus_plugin(name, _mapping(bus), bus_kinds, doc, registry)
    devices = _mapping(data.get("devices"))
    for name, dev in devices.items():
        out += _check_device_plugin(name, _mapping(dev), devices, bus_kinds, doc, registry)
    for name, est in _mapping(data.get("estimators")).items():
        out += _check_estimator_plugin(name, _mapping(est), doc, registry)
    for name, settings in _mapping(data.get("outputs")).items():
        out += _check_sink_plugin(name, settings, doc, registry)
    out += _check_scenario(_mapping(data.get("emulation")), doc, registry)
    return out


def _check_bus_plugin(name: Any, bus: dict[Any, Any], bus_kinds: dict[str, BusKind | None],
                      doc: LocatedDocument, registry: Registry) -> list[str]:
    """A bus's kind is installed and its settings fit; records its kind in ``bus_kinds``."""
    path: Path = ("buses", name)
    kind_name = _text(bus.get("kind"))
    if kind_name is None:
        return []
    factory = registry.buses.entries.get(kind_name)
    if factory is None:
        bus_kinds[name] = None
        return [f"{doc.where((*path, 'kind'))}: {dotted((*path, 'kind'))}: unknown bus kind "
                f"{kind_name!r}; installed: {', '.join(registry.buses.names())}"]
    bus_kinds[name] = factory.obj.kind
    settings = {k: v for k, v in bus.items() if k != "kind"}
    return _validate(factory.obj.Settings, settings, doc, path)


def _check_device_plugin(name: Any, dev: dict[Any, Any], devices: dict[Any, Any],
                         bus_kinds: dict[str, BusKind | None], doc: LocatedDocument,
                         registry: Registry) -> list[str]:
    """A device's driver is installed, fits its bus, and its settings and calibration
    records fit the driver."""
    path: Path = ("devices", name)
    driver_name = _text(dev.get("driver"))
    if driver_name is None:
        return []
    reg = registry.drivers.entries.get(driver_name)
    if reg is None:
        return [f"{doc.where((*path, 'driver'))}: {dotted((*path, 'driver'))}: no driver "
                f"named {driver_name!r} is installed; installed: "
                f"{', '.join(registry.drivers.names()) or 'none'} (see `imuhal plugins`)"]
    driver = reg.obj
    out = []
    bus_ref = _text(dev.get("bus")) or ""
    kind, problem = _bus_kind(devices, bus_ref, bus_kinds, registry)
    if problem:
        out.append(f"{doc.where((*path, 'bus'))}: {dotted((*path, 'bus'))}: {problem}")
    if kind is not None and kind not in driver.bus_kinds:
        allowed = ", ".join(sorted(k.value for k in driver.bus_kinds))
        out.append(f"{doc.where((*path, 'bus'))}: {dotted((*path, 'bus'))}: {driver_name} "
                   f"cannot sit on a {kind.value} bus; it supports: {allowed}")
    settings = dev.get("settings", {})
    if isinstance(settings, dict):
        context = {BUS_CONTEXT: bus_ref,
                   BUS_FEATURES_CONTEXT: _bus_features(devices, bus_ref, registry)}
        out += _validate(driver.Settings, settings, doc, (*path, "settings"), context)
    vectors = [q.name for q in driver.channels if _calibratable(q.name, registry)]
    for key in _calibration_keys(dev.get("calibration")):
        if key not in vectors:
            where = (*path, "calibration", key)
            out.append(f"{doc.where(where)}: {dotted(where)}: {driver_name} measures no "
                       f"vector quantity {key!r}; it can hold calibration for: "
                       f"{', '.join(vectors) or 'nothing'}")
    return out


def _check_estimator_plugin(name: Any, est: dict[Any, Any], doc: LocatedDocument,
                            registry: Registry) -> list[str]:
    path: Path = ("estimators", name)
    est_name = _text(est.get("estimator"))
    if est_name is None:
        return []
    reg_e = registry.estimators.entries.get(est_name)
    if reg_e is None:
        return [f"{doc.where((*path, 'estimator'))}: {dotted((*path, 'estimator'))}: no "
                f"estimator named {est_name!r} is installed; installed: "
                f"{', '.join(registry.estimators.names()) or 'none'}"]
    settings = est.get("settings", {})
    if not isinstance(settings, dict):
        return []
    return _validate(reg_e.obj.Settings, settings, doc, (*path, "settings"))


def _check_sink_plugin(name: Any, settings: Any, doc: LocatedDocument,
                       registry: Registry) -> list[str]:
    if name in OutputsConfig.model_fields:
        return []  # a built-in output's section: typed in the profile model
    reg_s = registry.sinks.entries.get(name)
    if reg_s is None:
        p_out: Path = ("outputs", name)
        return [f"{doc.where(p_out)}: {dotted(p_out)}: no sink named {name!r} is "
                f"installed; installed: {', '.join(registry.sinks.names()) or 'none'}"]
    if not isinstance(settings, dict):
        return []
    return _validate(reg_s.obj.Settings, settings, doc, ("outputs", name))


def _check_scenario(emulation: dict[Any, Any], doc: LocatedDocument,
                    registry: Registry) -> list[str]:
    """The emulated scenario is installed and its parameters fit it."""
    scenario = _text(emulation.get("scenario", "thermal"))
    if scenario is None:
        return []
    if registry.scenarios.entries and scenario not in registry.scenarios.entries:
        p: Path = ("emulation", "scenario")
        return [f"{doc.where(p)}: {dotted(p)}: unknown scenario {scenario!r}; installed: "
                f"{', '.join(registry.scenarios.names())}"]
    if scenario not in registry.scenarios.entries:
        return []
    # what `run --emulate` builds the scenario from: checked here as run would
    params = emulation.get("scenario_params", {})
    if not isinstance(params, dict):
        return []
    return _validate(registry.scenarios.entries[scenario].obj.Params, params, doc,
                     ("emulation", "scenario_params"))


def _check_fault_support(profile: BoardProfile, doc: LocatedDocument,
                         registry: Registry) -> list[str]:
    """Chip-level faults need an emulator that models them (ChipEmulator.chip_faults);
    ``corrupt_byte`` needs a serial line."""
    out = []
    for i, fault in enumerate(profile.emulation.faults):
        dev = profile.devices.get(fault.device)
        if dev is None:
            continue
        path: Path = ("emulation", "faults", i, "kind")
        if fault.kind == "corrupt_byte":
            bus = profile.buses.get(dev.bus)
            factory = registry.buses.entries.get(bus.kind) if bus is not None else None
            # a bus a chip provides (no profile bus) is a register bus behind that chip
            if bus is None or (factory is not None and factory.obj.kind is not BusKind.SERIAL):
                out.append(f"{doc.where(path)}: {dotted(path)}: corrupt_byte acts on a serial "
                           f"line; {fault.device!r} is on {dev.bus!r} (use bus_errors)")
            continue
        if fault.kind not in CHIP_FAULT_KINDS:
            continue
        reg = registry.emulators.entries.get(dev.driver)
        if reg is None:
            continue  # running emulated reports the missing emulator itself
        supported = reg.obj.chip_faults()
        if fault.kind not in supported:
            out.append(f"{doc.where(path)}: {dotted(path)}: the {dev.driver} emulator does not "
                       f"model {fault.kind!r}; it models: {', '.join(sorted(supported))}")
    return out
