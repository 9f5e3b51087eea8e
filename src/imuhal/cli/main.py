"""``imuhal``: the command line. Each command lives in its own module with ``add_parser``.

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
    plot_cmd,
    plugins_cmd,
    profile_cmd,
    replay_cmd,
    run_cmd,
)
from imuhal.core.errors import ImuhalError
from imuhal.plugins.manager import load_registry

EXIT_ERROR = 2
EXIT_INTERNAL = 70
EXIT_INTERRUPTED = 130

COMMANDS = [run_cmd, replay_cmd, estimate_cmd, plot_cmd, calibrate_cmd, check_mounts_cmd,
            plugins_cmd, profile_cmd]
"""Modules providing ``add_parser(subparsers)``; the order is the order in --help."""


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="imuhal",
        description="Orientation, altitude and climb rate from IMU and barometer boards.",
    )
    parser.add_argument("--version", action="version", version=f"imuhal {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for module in COMMANDS:
        module.add_parser(sub)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if args.command is None:
        parser.print_help()
        return 0
    debug = os.environ.get("IMUHAL_DEBUG") == "1"
    try:
        registry = load_registry()
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
