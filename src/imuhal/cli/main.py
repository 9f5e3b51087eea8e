"""``imuhal``: the command line. Each command lives in its own module with ``add_parser``;
plugins add commands through the ``imuhal_register_commands`` hook.

Errors are one clear message and a non-zero exit, never a traceback (set IMUHAL_DEBUG=1 to
see one).
"""

from __future__ import annotations

import argparse
import os
import sys
from collections.abc import Sequence

from imuhal import __version__
from imuhal.cli import (
    calibrate_cmd,
    check_mounts_cmd,
    estimate_cmd,
    evaluate_cmd,
    plugins_cmd,
    profile_cmd,
    run_cmd,
)
from imuhal.core.errors import ImuhalError, PluginError
from imuhal.plugins.manager import Registry, load_registry

EXIT_ERROR = 2
EXIT_INTERNAL = 70
EXIT_INTERRUPTED = 130

COMMANDS = [run_cmd, estimate_cmd, evaluate_cmd, calibrate_cmd, check_mounts_cmd, plugins_cmd,
            profile_cmd]
"""Modules providing ``add_parser(subparsers)``; the order is the order in --help."""


def build_parser(registry: Registry | None = None) -> argparse.ArgumentParser:
    """The parser of the built-in commands, plus the commands ``registry``'s plugins add."""
    parser = argparse.ArgumentParser(
        prog="imuhal",
        description="Orientation, altitude and climb rate from IMU and barometer boards.",
    )
    parser.add_argument("--version", action="version", version=f"imuhal {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for module in COMMANDS:
        module.add_parser(sub)
    if registry is not None:
        for name in registry.commands.names():
            reg = registry.commands.entries[name]
            if name in sub.choices:
                raise PluginError(
                    f"plugin {reg.plugin!r} registered the command {name!r}, which imuhal "
                    f"already has; the plugin must rename it (or set IMUHAL_DISABLE_PLUGINS="
                    f"{reg.plugin} to skip the plugin)")
            command = reg.obj()
            cmd_parser = sub.add_parser(name, help=command.help or None,
                                        description=command.description or command.help or None)
            command.add_arguments(cmd_parser)
            cmd_parser.set_defaults(func=command.run)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    debug = os.environ.get("IMUHAL_DEBUG") == "1"
    # Plugins are loaded first (they may add commands); when one is broken, --help and
    # --version still work and any command reports the plugin's error.
    registry: Registry | None = None
    load_error: ImuhalError | None = None
    try:
        registry = load_registry()
        parser = build_parser(registry)
    except ImuhalError as exc:
        load_error = exc
        parser = build_parser()
    args = parser.parse_args(argv)
    if args.command is None:
        parser.print_help()
        return 0
    try:
        if load_error is not None:
            raise load_error
        return int(args.func(args, registry))
    except ImuhalError as exc:
        if debug:
            raise
        print(f"imuhal: error: {exc}", file=sys.stderr)
        return EXIT_ERROR
    except KeyboardInterrupt:
        return EXIT_INTERRUPTED
    except BrokenPipeError:
        return 0
    except Exception as exc:
        if debug:
            raise
        print(f"imuhal: internal error: {type(exc).__name__}: {exc}\n"
              "This is a bug; rerun with IMUHAL_DEBUG=1 for a traceback and report it.",
              file=sys.stderr)
        return EXIT_INTERNAL


if __name__ == "__main__":
    sys.exit(main())
