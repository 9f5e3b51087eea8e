"""``imuhal``: the command line. Each command lives in its own module with ``add_parser``.

Errors are one clear message and a non-zero exit, never a traceback (set IMUHAL_DEBUG=1 to
see one).
"""

from __future__ import annotations

import argparse
import contextlib
import os
import signal
import sys
from collections.abc import Iterator, Sequence
from types import FrameType

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
from imuhal.cli.args import OneLineParser
from imuhal.core.errors import ImuhalError
from imuhal.plugins.manager import load_registry

EXIT_ERROR = 2
EXIT_INTERNAL = 70
EXIT_INTERRUPTED = 130

COMMANDS = [run_cmd, estimate_cmd, evaluate_cmd, calibrate_cmd, check_mounts_cmd, plugins_cmd,
            profile_cmd]
"""Modules providing ``add_parser(subparsers)``; the order is the order in --help."""


def build_parser() -> argparse.ArgumentParser:
    parser = OneLineParser(
        prog="imuhal",
        description="Orientation, altitude and climb rate from IMU and barometer boards.",
    )
    parser.add_argument("--version", action="version", version=f"imuhal {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for module in COMMANDS:
        module.add_parser(sub)
    return parser


class StopRequested(KeyboardInterrupt):
    """SIGTERM or SIGHUP, turned into the same clean stop as Ctrl-C: a logger stopped by its
    service manager or a closed ssh session finalizes its log under its own name."""

    def __init__(self, signum: int) -> None:
        super().__init__(signal.Signals(signum).name)
        self.signum = signum


STOP_SIGNALS = tuple(getattr(signal, name) for name in ("SIGTERM", "SIGHUP", "SIGINT")
                     if hasattr(signal, name))


@contextlib.contextmanager
def stop_signals_as_interrupts() -> Iterator[None]:
    """While the command runs, SIGTERM, SIGHUP and SIGINT raise :class:`StopRequested` (a
    KeyboardInterrupt, as Ctrl-C always did). Once a stop is under way, further signals are
    ignored so that finalizing the files is not interrupted. Previous handlers are restored
    afterwards."""
    stopping = False

    def handler(signum: int, frame: FrameType | None) -> None:
        nonlocal stopping
        if stopping:
            return
        stopping = True
        raise StopRequested(signum)

    try:
        previous = {s: signal.signal(s, handler) for s in STOP_SIGNALS}
    except ValueError:  # not the main thread (embedded use): leave signals alone
        yield
        return
    try:
        yield
    finally:
        for s, h in previous.items():
            signal.signal(s, h)


def main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if args.command is None:
        parser.print_help()
        return 0
    debug = os.environ.get("IMUHAL_DEBUG") == "1"
    try:
        with stop_signals_as_interrupts():
            registry = load_registry()
            return int(args.func(args, registry))
    except ImuhalError as exc:
        if debug:
            raise
        print(f"imuhal: error: {exc}", file=sys.stderr)
        return EXIT_ERROR
    except StopRequested as stop:
        return 128 + stop.signum
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
