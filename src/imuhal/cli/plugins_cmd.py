"""``imuhal plugins``: what is installed, and which plugin of which distribution (and its
version) provides it."""

from __future__ import annotations

import argparse
from typing import Any

from imuhal.plugins.manager import Registry
from imuhal.plugins.registrars import Registrar


def add_parser(sub: Any) -> None:
    plugins = sub.add_parser("plugins", help="list installed drivers, estimators, buses, "
                             "scenarios, quantities, sinks and commands")
    plugins.set_defaults(func=cmd_plugins)


def cmd_plugins(args: argparse.Namespace, registry: Registry) -> int:
    sections: list[tuple[str, Registrar[Any]]] = [
        ("drivers", registry.drivers),
        ("emulators", registry.emulators),
        ("estimators", registry.estimators),
        ("bus kinds", registry.buses),
        ("scenarios", registry.scenarios),
        ("quantities", registry.quantities),
        ("sinks", registry.sinks),
        ("commands", registry.commands),
        ("calibration procedures", registry.calibrations),
    ]
    for title, registrar in sections:
        print(f"{title}:")
        if not registrar.entries:
            print("  (none)")
        for name in registrar.names():
            reg = registrar.entries[name]
            desc = getattr(reg.obj, "description", "") or getattr(reg.obj, "help", "") or ""
            quantity = getattr(reg.obj, "channel", None) if registrar is registry.quantities \
                else None
            if quantity is not None:
                shape = "vector" if quantity.is_vector else "scalar"
                desc = f"{shape}, {quantity.unit}: {quantity.description}"
            version = registry.versions.get(reg.plugin, "")
            origin = f"{reg.package or '(local)'}:{reg.plugin}" + (f" {version}" if version
                                                                 else "")
            print(f"  {name:<18} {origin:<30} {desc}")
    return 0
