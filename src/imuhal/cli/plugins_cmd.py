"""``imuhal plugins``: what is installed, and which package provides it."""

from __future__ import annotations

import argparse
from typing import Any

from imuhal.plugins.manager import Registry


def add_parser(sub: Any) -> None:
    plugins = sub.add_parser("plugins", help="list installed drivers, estimators, buses, "
                             "scenarios, sinks")
    plugins.set_defaults(func=cmd_plugins)


def cmd_plugins(args: argparse.Namespace, registry: Registry) -> int:
    sections = [
        ("drivers", registry.drivers),
        ("emulators", registry.emulators),
        ("estimators", registry.estimators),
        ("bus kinds", registry.buses),
        ("scenarios", registry.scenarios),
        ("sinks", registry.sinks),
    ]
    for title, registrar in sections:
        print(f"{title}:")
        if not registrar.entries:
            print("  (none)")
        for name in registrar.names():
            reg = registrar.entries[name]
            desc = getattr(reg.obj, "description", "") or ""
            origin = f"{reg.package or '(local)'}:{reg.plugin}"
            print(f"  {name:<18} {origin:<24} {desc}")
    return 0
