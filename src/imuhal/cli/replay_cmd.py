"""``imuhal replay FILE``: decode a bus recording again, with today's drivers and estimators."""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path
from typing import Any

from imuhal.cli.robot_outputs import add_mcap_argument, mcap_sink, report_mcap
from imuhal.core.atomic import check_outputs
from imuhal.core.errors import ImuhalError
from imuhal.offline.replay import (
    ReplayDivergence,
    open_replay,
    replay_pipeline,
    replay_run,
)
from imuhal.plugins.manager import Registry
from imuhal.profile.loader import load_profile


def add_parser(sub: Any) -> None:
    p = sub.add_parser(
        "replay", help="replay a bus recording (run --record) through the drivers",
        description="Feed a recording made with `imuhal run --record FILE` to the drivers and "
        "estimators again, on the recorded clock: the same samples and estimates as the live "
        "run, or a one-line message naming the first transaction a driver now asks "
        "differently. Uses the profile stored in the recording unless --profile is given.",
    )
    p.add_argument("recording", metavar="FILE", help="a recording from `imuhal run --record`")
    p.add_argument("--profile", metavar="PROFILE.yaml",
                   help="decode with this profile instead of the recorded one (same bus names)")
    p.add_argument("--output", metavar="FILE.csv", help="write estimates to a CSV file")
    p.add_argument("--samples", action="store_true",
                   help="with --output, also write every sample (flagged ones included)")
    add_mcap_argument(p)
    p.add_argument("--quiet", action="store_true", help="no status line")
    p.set_defaults(func=cmd_replay)


def cmd_replay(args: argparse.Namespace, registry: Registry) -> int:
    from imuhal.pipeline import ConsoleSink, CsvSink

    # Before anything is decoded: the log must not replace the recording or the profile.
    check_outputs({"--output": args.output, "--mcap": args.mcap},
                  {"FILE": args.recording, "--profile": args.profile})
    if args.samples and not args.output:
        raise ImuhalError("--samples writes the samples into the --output log; add "
                          "--output FILE.csv")
    profile = load_profile(args.profile, registry) if args.profile else None
    replay = open_replay(args.recording, registry, profile)
    header = replay.recording.header
    print(f"replaying {args.recording}: {replay.profile.name}, recorded "
          f"{header.get('created_utc', '?')} by imuhal {header.get('imuhal_version', '?')}",
          file=sys.stderr)
    wall0 = time.perf_counter()
    try:
        pipeline = replay_pipeline(replay, registry)
    except ReplayDivergence as exc:
        raise ImuhalError(f"{exc} (while opening the board)") from None
    opened_ns = replay.source.t_ns  # the run's time counts from here, as live
    for w in pipeline.warnings:
        print(f"warning: {w}", file=sys.stderr)
    sinks: list[Any] = [] if args.quiet else [ConsoleSink(sys.stdout)]
    csv_sink = CsvSink(args.output, include_samples=args.samples) if args.output else None
    if csv_sink is not None:
        sinks.append(csv_sink)
    mcap = mcap_sink(registry, args.mcap, replay.profile) if args.mcap else None
    if mcap is not None:
        sinks.append(mcap)
    try:
        replay_run(pipeline, sinks)
    except ReplayDivergence as exc:
        for sink in (csv_sink, mcap):
            if sink is not None:
                sink.abort()  # a diverged decode must not replace a good output
        raise ImuhalError(str(exc)) from None
    for sink in sinks:
        sink.close()
    summary = pipeline.summary(wall_s=time.perf_counter() - wall0,
                               simulated_s=(replay.source.t_ns - opened_ns) / 1e9)
    print(summary.describe(), file=sys.stderr)
    recording = replay.recording
    if recording.damage:
        print(f"warning: replayed up to the damage: {recording.damage}", file=sys.stderr)
    elif recording.end is None:
        print(f"warning: {Path(args.recording)} has no end mark (the run was cut off, e.g. "
              "by a power cut); replayed up to its last flush", file=sys.stderr)
    elif recording.end.how != "complete":
        print(f"note: the recorded run ended: {recording.end.how}", file=sys.stderr)
    print(f"replayed {replay.source.transfers} bus transactions", file=sys.stderr)
    if csv_sink is not None:
        print(f"wrote {csv_sink.rows} rows to {args.output}", file=sys.stderr)
    if mcap is not None:
        print(report_mcap(mcap, args.mcap), file=sys.stderr)
    return 0
