"""``imuhal``: the command line. Each command lives in its own module with ``add_parser``;
plugins add commands through the ``imuhal_register_commands`` hook.

Errors are one clear message and a non-zero exit, never a traceback (set IMUHAL_DEBUG=1 to
see one).
"""

from __future__ import annotations

import argparse
import contextlib
import os
import signal
import sys
import warnings
from collections.abc import Iterator, Sequence
from types import FrameType

from imuhal import __version__
from imuhal.cli import (
    calibrate_cmd,
    check_mounts_cmd,
    estimate_cmd,
    evaluate_cmd,
    igc_cmd,
    plot_cmd,
    plugins_cmd,
    profile_cmd,
    replay_cmd,
    run_cmd,
)
from imuhal.cli.args import OneLineParser
from imuhal.core.errors import ImuhalDeprecationWarning, ImuhalError, PluginError
from imuhal.plugins.manager import Registry, load_registry

EXIT_ERROR = 2
EXIT_INTERNAL = 70
EXIT_INTERRUPTED = 130

COMMANDS = [run_cmd, replay_cmd, estimate_cmd, evaluate_cmd, plot_cmd, calibrate_cmd,
            check_mounts_cmd, igc_cmd, plugins_cmd, profile_cmd]
"""Modules providing ``add_parser(subparsers)``; the order is the order in --help."""


def build_parser(registry: Registry | None = None) -> argparse.ArgumentParser:
    """The parser of the built-in commands, plus the commands ``registry``'s plugins add."""
    parser = OneLineParser(
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


@contextlib.contextmanager
def old_names_shown() -> Iterator[None]:
    """Show each old-name warning (``ImuhalDeprecationWarning``: an old setting name that
    still works) once, as one line on stderr naming the old and the new key; Python would
    hide it from a CLI user."""
    seen: set[str] = set()

    def show(message: Warning | str, category: type[Warning], *rest: object) -> None:
        text = str(message)
        if text not in seen:
            seen.add(text)
            print(f"imuhal: warning: {text}", file=sys.stderr)

    with warnings.catch_warnings():
        warnings.simplefilter("always", ImuhalDeprecationWarning)
        previous, warnings.showwarning = warnings.showwarning, show  # type: ignore[assignment]  # warnings.showwarning's replacement has its signature; typeshed types the module attribute as a def
        try:
            yield
        finally:
            warnings.showwarning = previous


def main(argv: Sequence[str] | None = None) -> int:
    debug = os.environ.get("IMUHAL_DEBUG") == "1"
    # Plugins are loaded first (they may add commands); when one is broken, --help and
    # --version still work and any command reports the plugin's error.
    registry: Registry | None = None
    load_error: ImuhalError | None = None
    try:
        with stop_signals_as_interrupts():
            registry = load_registry()
            parser = build_parser(registry)
    except ImuhalError as exc:
        load_error = exc
        parser = build_parser()
    except StopRequested as stop:  # SIGTERM/SIGHUP while plugins load: no traceback
        return 128 + stop.signum
    except KeyboardInterrupt:  # Ctrl-C while plugins load
        return EXIT_INTERRUPTED
    args = parser.parse_args(argv)
    if args.command is None:
        parser.print_help()
        return 0
    try:
        with stop_signals_as_interrupts(), old_names_shown():
            if load_error is not None:
                raise load_error
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
