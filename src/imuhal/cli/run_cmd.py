"""``imuhal run``: run a board profile on hardware or emulated."""

from __future__ import annotations

import argparse
import contextlib
import sys
from pathlib import Path
from typing import Any

from imuhal import __version__
from imuhal.bus.recording.format import RecordingWriteFailed
from imuhal.bus.recording.recorder import BusRecorder, run_header
from imuhal.bus.spy import format_transfer
from imuhal.cli.frame_option import frame_argument
from imuhal.core.atomic import AtomicFile
from imuhal.core.errors import ImuhalError
from imuhal.live import LiveView, parse_bind
from imuhal.plugins.manager import Registry
from imuhal.profile.loader import load_profile
from imuhal.profiles_dir import default_profile_path

REPLAY_SCENARIO = "replay"
"""The scenario that flies a recorded truth file (imuhal.sim.recorded)."""


def add_parser(sub: Any) -> None:
    run = sub.add_parser(
        "run", help="run a board profile (default: the seed vario board, emulated)",
        description="Run the pipeline. With no PROFILE: the bundled seed paragliding vario "
        "board, emulated, flying its default scenario. A PROFILE without --emulate opens "
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
    run.add_argument("--output-frame", type=frame_argument, metavar="NAME",
                     help="convention of the CSV log and console line (ned, aerospace, "
                     "enu/ros, android, win8; default: the profile's output_frame)")
    run.add_argument("--samples", action="store_true",
                     help="with --output, also write every sample (flagged ones included)")
    run.add_argument("--truth", metavar="FILE.csv",
                     help="emulated runs: write the simulated ground truth at the same "
                     "timestamps as the --output rows (docs/simulation.md); with "
                     "--emulate replay: the truth file to fly again (read, never written)")
    run.add_argument("--trace", metavar="FILE.txt",
                     help="log every bus transaction (time, bus, address, bytes) to a file")
    run.add_argument("--record", metavar="FILE",
                     help="record every bus transaction and clock reading to a new binary "
                     "file, for `imuhal replay` (docs/recording.md)")
    run.add_argument("--seed", type=int, help="seed of the simulated world (default: profile's)")
    run.add_argument("--quiet", action="store_true", help="no live status line")
    run.add_argument("--web", metavar="[HOST:]PORT",
                     help="serve a live dashboard (read-only) on PORT of this machine only, "
                     "or of HOST when named (0.0.0.0: every interface); emulated runs are "
                     "paced in real time (docs/live-view.md)")
    run.set_defaults(func=cmd_run)


def cmd_run(args: argparse.Namespace, registry: Registry) -> int:
    from imuhal.emulation import EmulatedBoard, TruthSink, open_emulated
    from imuhal.pipeline import ConsoleSink, CsvSink, Pipeline

    path = Path(args.profile) if args.profile else default_profile_path()
    profile = load_profile(path, registry)
    frame = args.output_frame or profile.output_frame
    emulate = args.emulate
    if args.profile is None and emulate is None:
        emulate = profile.emulation.scenario
    web = parse_bind(args.web) if args.web is not None else None
    # Real buses always run in real time; a dashboard of an emulated run is watched live.
    realtime = args.realtime or emulate is None or web is not None
    if args.truth and emulate is None:
        raise ImuhalError("--truth needs an emulated run (--emulate SCENARIO): real "
                          "hardware has no ground truth")
    truth_out, scenario_params = args.truth, None
    if emulate == REPLAY_SCENARIO:
        # The truth is the input here: the trajectory to fly again.
        if not args.truth:
            raise ImuhalError("--emulate replay flies a recorded truth file again: name it "
                              "with --truth FILE.csv (one that `imuhal run --truth` wrote)")
        if not Path(args.truth).is_file():
            raise ImuhalError(f"{args.truth}: no such truth file to replay; write one with "
                              "`imuhal run --emulate SCENARIO --truth FILE.csv`")
        truth_out, scenario_params = None, {"path": args.truth}
    duration = args.duration
    if duration is None and emulate is not None and scenario_params is None:
        duration = registry.scenarios.get(emulate).default_duration_s
    where = f"emulated, scenario '{emulate}'" if emulate else "real hardware"
    print(f"imuhal {__version__}: {profile.name} ({where}) from {path}", file=sys.stderr)
    sinks: list[Any] = []
    if not args.quiet:
        sinks.append(ConsoleSink(sys.stdout, frame=frame))
    csv_sink = None
    trace_file = AtomicFile(args.trace) if args.trace else None
    trace = (lambda t: trace_file.write(format_transfer(t) + "\n")) if trace_file else None
    recorder = None
    ended = ["failed"]  # how the run ended, for the recording's end mark
    with contextlib.ExitStack() as stack:
        if trace_file is not None:
            # Committed even when opening the board fails: the trace of a failed probe is
            # exactly what a bug report needs.
            stack.callback(trace_file.commit)
        if args.record:
            recorder = BusRecorder(args.record, run_header(
                path.read_text(encoding="utf-8"), str(path), emulate=emulate, seed=args.seed))
            stack.callback(lambda: recorder.close(ended[0]))
        if emulate is None:
            pipeline = stack.enter_context(Pipeline.open(profile, registry, trace=trace,
                                                         recorder=recorder))
        else:
            try:
                pipeline = stack.enter_context(open_emulated(
                    profile, registry, scenario=emulate, realtime=realtime, seed=args.seed,
                    trace=trace, recorder=recorder, scenario_params=scenario_params))
            except ValueError as exc:
                if scenario_params is None:
                    raise
                raise ImuhalError(f"{args.truth}: cannot replay this truth file: {exc}"
                                  ) from None
        if duration is None and isinstance(pipeline.board, EmulatedBoard):
            duration = pipeline.board.scenario.duration_s  # type: ignore[attr-defined]
        for w in pipeline.warnings:
            print(f"warning: {w}", file=sys.stderr)
        if web is not None:
            live = stack.enter_context(LiveView.for_pipeline(pipeline, host=web.host,
                                                             port=web.port))
            sinks.append(live.sink)
            print(f"live view: {live.url}" + ("" if web.loopback else
                  " (reachable from the network at this machine's address: read-only, "
                  "no password; docs/live-view.md)"), file=sys.stderr)
        if args.output:
            csv_sink = CsvSink(args.output, include_samples=args.samples, frame=frame)
            sinks.append(csv_sink)
        truth_sink = None
        if truth_out and isinstance(pipeline.board, EmulatedBoard):
            truth_sink = TruthSink(truth_out, pipeline.board.scenario,
                                   include_samples=args.samples)
            sinks.append(truth_sink)
        try:
            summary = pipeline.run(duration, sinks)
            ended[0] = "complete"
        except RecordingWriteFailed as exc:
            raise ImuhalError(f"{exc}; the run stopped (the file keeps what was flushed)"
                              ) from None
        except KeyboardInterrupt:
            summary = pipeline.summary()
            ended[0] = "interrupted"
            print("\ninterrupted", file=sys.stderr)
    print(summary.describe(), file=sys.stderr)
    if csv_sink is not None:
        print(f"wrote {csv_sink.rows} rows to {args.output}", file=sys.stderr)
    if truth_sink is not None:
        print(f"wrote {truth_sink.rows} truth rows to {truth_out}", file=sys.stderr)
    if recorder is not None:
        print(f"recorded {recorder.transfers} bus transactions to {args.record}",
              file=sys.stderr)
    return 0
