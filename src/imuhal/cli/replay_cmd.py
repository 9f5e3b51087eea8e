"""``imuhal replay FILE``: decode a bus recording again, with today's drivers and estimators."""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path
from typing import Any

from imuhal.cli.replay_options import ReplayOptions
from imuhal.cli.robot_outputs import add_mcap_argument, mcap_sink, report_mcap
from imuhal.cli.sink_options import add_sink_arguments, describe_sinks, sink_counts
from imuhal.core.atomic import check_outputs
from imuhal.core.errors import ImuhalError
from imuhal.offline.replay import (
    ReplayDivergence,
    WallClockPace,
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
    add_sink_arguments(p)
    p.add_argument("--realtime", action="store_true",
                   help="hand the events to the outputs at the recorded pace (wall clock), "
                   "as the live run did: a broker or a ground station sees a board, not a "
                   "burst")
    p.add_argument("--quiet", action="store_true", help="no status line")
    p.set_defaults(func=cmd_replay)


def cmd_replay(args: argparse.Namespace, registry: Registry) -> int:
    opts = ReplayOptions.from_args(args)
    # Before anything is decoded: the log must not replace the recording or the profile.
    check_outputs(opts.outputs(), {"FILE": opts.recording, "--profile": opts.profile})
    profile = load_profile(opts.profile, registry) if opts.profile else None
    replay = open_replay(opts.recording, registry, profile)
    # built (and so checked) before anything is decoded; the recorded profile configures them
    plugin_sinks = opts.plugin_sinks(registry, board=replay.profile.name,
                                     outputs=replay.profile.outputs.plugin_sections(),
                                     frame=replay.profile.output_frame)
    header = replay.recording.header
    print(f"replaying {opts.recording}: {replay.profile.name}, recorded "
          f"{header.get('created_utc', '?')} by imuhal {header.get('imuhal_version', '?')}",
          file=sys.stderr)
    wall0 = time.perf_counter()
    try:
        pipeline = replay_pipeline(replay, registry)
    except ReplayDivergence as exc:
        _close(plugin_sinks)
        raise ImuhalError(f"{exc} (while opening the board)") from None
    opened_ns = replay.source.t_ns  # the run's time counts from here, as live
    for w in pipeline.warnings:
        print(f"warning: {w}", file=sys.stderr)
    outputs = _ReplayOutputs(opts, registry, replay.profile, plugin_sinks)
    outputs.run(pipeline)
    summary = pipeline.summary(wall_s=time.perf_counter() - wall0,
                               simulated_s=(replay.source.t_ns - opened_ns) / 1e9)
    summary.sinks = sink_counts(plugin_sinks)
    print(summary.describe(), file=sys.stderr)
    _report_recording(replay, opts.recording)
    outputs.report()
    return 0


class _ReplayOutputs:
    """The replay's sinks in the order they see each event: the pace (``--realtime``), the
    status line, the CSV log, the MCAP file and the plugin sinks."""

    def __init__(self, opts: ReplayOptions, registry: Registry, profile: Any,
                 plugin_sinks: list[Any]) -> None:
        from imuhal.pipeline import ConsoleSink, CsvSink

        self.opts = opts
        self.plugin_sinks = plugin_sinks
        frame = profile.output_frame  # as the live run without --output-frame
        self.sinks: list[Any] = [WallClockPace()] if opts.realtime else []
        if not opts.quiet:
            self.sinks.append(ConsoleSink(sys.stdout, frame=frame))
        self.csv = (CsvSink(opts.output, include_samples=opts.samples, frame=frame)
                    if opts.output else None)
        self.mcap = mcap_sink(registry, opts.mcap, profile) if opts.mcap else None
        self.sinks += [s for s in (self.csv, self.mcap) if s is not None]
        self.sinks += plugin_sinks
        describe_sinks(plugin_sinks)

    def run(self, pipeline: Any) -> None:
        """Replays into the sinks and closes them; a diverged decode aborts the files (it
        must not replace a good output) and closes the plugin sinks (a broker keeps what it
        was handed)."""
        try:
            replay_run(pipeline, self.sinks)
        except ReplayDivergence as exc:
            for sink in (self.csv, self.mcap):
                if sink is not None:
                    sink.abort()
            _close(self.plugin_sinks)
            raise ImuhalError(str(exc)) from None
        except BaseException:
            _close(self.plugin_sinks)
            raise
        _close(self.sinks)

    def report(self) -> None:
        """The closing lines about the files written."""
        if self.csv is not None:
            print(f"wrote {self.csv.rows} rows to {self.opts.output}", file=sys.stderr)
        if self.mcap is not None:
            print(report_mcap(self.mcap, str(self.opts.mcap)), file=sys.stderr)


def _close(sinks: list[Any]) -> None:
    for sink in sinks:
        sink.close()


def _report_recording(replay: Any, path: str) -> None:
    """How the recording ended, when not complete, and how much of it was replayed."""
    recording = replay.recording
    if recording.damage:
        print(f"warning: replayed up to the damage: {recording.damage}", file=sys.stderr)
    elif recording.end is None:
        print(f"warning: {Path(path)} has no end mark (the run was cut off, e.g. "
              "by a power cut); replayed up to its last flush", file=sys.stderr)
    elif recording.end.how != "complete":
        print(f"note: the recorded run ended: {recording.end.how}", file=sys.stderr)
    print(f"replayed {replay.source.transfers} bus transactions", file=sys.stderr)
