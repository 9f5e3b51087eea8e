"""``imuhal``: run a board, list plugins, check profiles.

Errors are one clear message and a non-zero exit, never a traceback (set IMUHAL_DEBUG=1 to
see one).
"""

from __future__ import annotations

import argparse
import os
import sys
from collections.abc import Sequence
from pathlib import Path

from imuhal import __version__
from imuhal.core.errors import ImuhalError
from imuhal.plugins.manager import Registry, load_registry
from imuhal.profile.loader import check_profile, load_profile
from imuhal.profiles_dir import default_profile_path

EXIT_ERROR = 2
EXIT_INTERNAL = 70
EXIT_INTERRUPTED = 130


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="imuhal",
        description="Orientation, altitude and climb rate from IMU and barometer boards.",
    )
    parser.add_argument("--version", action="version", version=f"imuhal {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")

    run = sub.add_parser(
        "run", help="run a board profile (default: the seed vario board, emulated)",
        description="Run the pipeline. With no PROFILE: the bundled seed paragliding vario "
        "board, emulated, flying the 'thermal' scenario. A PROFILE without --emulate opens "
        "the real buses it names and always runs in real time.",
    )
    run.add_argument("profile", nargs="?", help="board profile YAML (default: bundled seed board)")
    run.add_argument("--emulate", metavar="SCENARIO",
                     help="emulate the board's chips flying SCENARIO (see `imuhal plugins`)")
    run.add_argument("--duration", type=float, metavar="SECONDS",
                     help="stop after this many seconds (default: the scenario's length, "
                     "or until Ctrl-C on hardware)")
    run.add_argument("--realtime", action="store_true",
                     help="pace an emulated run at wall-clock speed")
    run.add_argument("--output", metavar="FILE.csv", help="write estimates to a CSV file")
    run.add_argument("--samples", action="store_true",
                     help="with --output, also write every sample (flagged ones included)")
    run.add_argument("--seed", type=int, help="seed of the simulated world (default: profile's)")
    run.add_argument("--quiet", action="store_true", help="no live status line")
    run.set_defaults(func=cmd_run)

    plugins = sub.add_parser("plugins", help="list installed drivers, estimators, buses, scenarios")
    plugins.set_defaults(func=cmd_plugins)

    profile = sub.add_parser("profile", help="work with board profiles")
    psub = profile.add_subparsers(dest="profile_command", metavar="ACTION")
    check = psub.add_parser("check", help="validate profiles; exit 0 when all are valid")
    check.add_argument("files", nargs="+", metavar="FILE")
    check.set_defaults(func=cmd_profile_check)
    profile.set_defaults(func=lambda args, registry: _usage(profile))
    return parser


def _usage(parser: argparse.ArgumentParser) -> int:
    parser.print_usage(sys.stderr)
    return EXIT_ERROR


def cmd_plugins(args: argparse.Namespace, registry: Registry) -> int:
    sections = [
        ("drivers", registry.drivers),
        ("emulators", registry.emulators),
        ("estimators", registry.estimators),
        ("bus kinds", registry.buses),
        ("scenarios", registry.scenarios),
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


def cmd_profile_check(args: argparse.Namespace, registry: Registry) -> int:
    bad = 0
    for file in args.files:
        problems = check_profile(file, registry)
        if problems:
            bad += 1
            print(f"{file}: INVALID ({len(problems)} problem{'s' if len(problems) > 1 else ''})")
            for p in problems:
                print(f"  {p}")
        else:
            print(f"{file}: ok")
    return EXIT_ERROR if bad else 0


def cmd_run(args: argparse.Namespace, registry: Registry) -> int:
    from imuhal.pipeline import ConsoleSink, CsvSink, Pipeline

    path = Path(args.profile) if args.profile else default_profile_path()
    profile = load_profile(path, registry)
    emulate = args.emulate
    if args.profile is None and emulate is None:
        emulate = profile.emulation.scenario
    if emulate is None and args.realtime is False:
        args.realtime = True  # real buses always run in real time
    duration = args.duration
    if duration is None and emulate is not None:
        duration = registry.scenarios.get(emulate).default_duration_s
    where = f"emulated, scenario '{emulate}'" if emulate else "real hardware"
    print(f"imuhal {__version__}: {profile.name} ({where}) from {path}", file=sys.stderr)
    sinks = []
    if not args.quiet:
        sinks.append(ConsoleSink(sys.stdout))
    csv_sink = None
    with Pipeline.open(profile, registry, emulate=emulate, realtime=args.realtime,
                       seed=args.seed) as pipeline:
        for w in pipeline.warnings:
            print(f"warning: {w}", file=sys.stderr)
        if args.output:
            csv_sink = CsvSink(args.output, include_samples=args.samples)
            sinks.append(csv_sink)
        try:
            summary = pipeline.run(duration, sinks)
        except KeyboardInterrupt:
            summary = pipeline.summary()
            print("\ninterrupted", file=sys.stderr)
    print(summary.describe(), file=sys.stderr)
    if csv_sink is not None:
        print(f"wrote {csv_sink.rows} rows to {args.output}", file=sys.stderr)
    return 0


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
