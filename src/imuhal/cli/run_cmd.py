"""``imuhal run``: run a board profile on hardware or emulated."""

from __future__ import annotations

import argparse
import contextlib
import math
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from imuhal import __version__
from imuhal.bus.recording.format import RecordingWriteFailed
from imuhal.bus.recording.recorder import BusRecorder, run_header
from imuhal.bus.spy import format_transfer
from imuhal.cli import args as types
from imuhal.cli.frame_option import frame_argument
from imuhal.cli.robot_outputs import (
    add_mavlink_arguments,
    add_mcap_argument,
    mavlink_sink,
    mcap_sink,
    report_mavlink,
    report_mcap,
)
from imuhal.cli.run_options import RunOptions
from imuhal.cli.sink_options import add_sink_arguments, describe_sinks, sink_counts
from imuhal.core.atomic import AtomicFile, check_outputs
from imuhal.core.errors import ImuhalError
from imuhal.live import LiveView, parse_bind
from imuhal.plugins.manager import Registry
from imuhal.profile.bundled import default_profile_path
from imuhal.profile.loader import load_profile

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
    run.add_argument("--duration", type=types.seconds, metavar="SECONDS",
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
                     "timestamps as the --output rows (docs/simulation.md); the truth file "
                     "to fly again is --replay-truth")
    run.add_argument("--trace", metavar="FILE.txt",
                     help="log every bus transaction (time, bus, address, bytes) to a file")
    run.add_argument("--nmea", action="append", default=[], metavar="OUTPUT",
                     help="send LK8EX1, LXWP0, POV, _PRS, XCTRC, GGA and RMC sentences to "
                     "a flight app: serial:PORT@BAUD, pty, pty:LINK (a symlink to the pty), "
                     "tcp:PORT (loopback), or ble / ble:NAME (Bluetooth LE; LK8EX1 and LXWP0 "
                     "by default); repeatable (docs/flight-instrument.md)")
    run.add_argument("--nmea-sentences", metavar="LIST",
                     help="comma-separated subset of LK8EX1,LXWP0,POV,PRS,XCTRC,GGA,RMC")
    run.add_argument("--audio", action="store_true",
                     help="play the vario tones live (needs imuhal[audio] and a sound device)")
    run.add_argument("--audio-wav", metavar="FILE.wav",
                     help="write the vario tones to a WAV file (the profile's audio curve)")
    run.add_argument("--audio-damping", type=float, metavar="SECONDS",
                     help="time constant of the climb rate the tones follow (default: the "
                     "profile's audio.damping_s, 0 = the vario's own output)")
    run.add_argument("--audio-sink-alarm", type=float, metavar="M_S",
                     help="sink alarm (a warble) at or below this climb rate, e.g. -5 "
                     "(default: the profile's audio.sink_alarm_m_s, none)")
    run.add_argument("--igc", metavar="FILE.IGC|FOLDER",
                     help="write an IGC flight log (B records from the GNSS and the "
                     "barometer; a folder gets the FAI file name); `imuhal igc verify` "
                     "checks it (docs/flight-instrument.md)")
    run.add_argument("--igc-pilot", metavar="NAME",
                     help="the IGC log's pilot (default: the profile's outputs.igc.pilot)")
    run.add_argument("--igc-glider", metavar="TYPE",
                     help="the IGC log's glider type (default: the profile's "
                     "outputs.igc.glider_type)")
    add_mcap_argument(run)
    add_mavlink_arguments(run)
    add_sink_arguments(run)
    run.add_argument("--seed", type=types.seed,
                     help="seed of the simulated world, 0 or more (default: the profile's)")
    run.add_argument("--replay-truth", metavar="TRUTH.csv",
                     help="with --emulate replay: the truth CSV to fly again (e.g. one that "
                     "`imuhal run --truth` wrote)")
    run.add_argument("--record", metavar="FILE",
                     help="record every bus transaction and clock reading to a new binary "
                     "file, for `imuhal replay` (docs/recording.md)")
    run.add_argument("--skip-calibration", action="store_true",
                     help="emulated runs: fly the board as the profile stores it; by default "
                     "the accelerometer and magnetometer calibrations it lacks are measured "
                     "first on the emulated board, as docs/calibration.md asks of a user")
    run.add_argument("--save-learned", metavar="FILE.yaml",
                     help="write a copy of the profile holding the calibrations learned in "
                     "flight (mag_in_flight: the magnetometer's hard iron; accel_in_flight: the "
                     "accelerometer's offset) once converged")
    run.add_argument("--quiet", action="store_true", help="no live status line")
    run.add_argument("--web", metavar="[HOST:]PORT",
                     help="serve a live dashboard (read-only) on PORT of this machine only, "
                     "or of HOST when named (0.0.0.0: every interface); emulated runs are "
                     "paced in real time (docs/live-view.md)")
    run.set_defaults(func=cmd_run)


def cmd_run(args: argparse.Namespace, registry: Registry) -> int:
    opts = RunOptions.from_args(args)
    path = Path(opts.profile) if opts.profile else default_profile_path()
    # Before anything is opened: no output may overwrite an input, and each must be writable.
    check_outputs(opts.outputs(), {"PROFILE": path, "--replay-truth": opts.replay_truth})
    if opts.igc:
        from imuhal.sinks.flight.igc import check_igc_output

        check_igc_output(opts.igc)
    plan = _plan(opts, path, registry)
    session = _RunSession(opts, plan)
    with contextlib.ExitStack() as stack:
        pipeline = session.open(stack, registry)
        session.add_outputs(stack, pipeline, registry)
        summary = session.run(pipeline)
        learned = _learned(pipeline)
    print(summary.describe(), file=sys.stderr)
    session.check_log()
    if opts.save_learned:
        _save_learned(opts.save_learned, plan.profile_text, path, learned, registry)
    session.report()
    return 0


@dataclass
class _RunPlan:
    """What the options and the profile decide before any bus or output is opened."""

    path: Path
    profile: Any
    profile_text: str
    calibrated_note: str
    """The line saying the emulated board was calibrated first (empty: it was not)."""
    frame: Any
    emulate: str | None
    web: Any
    realtime: bool
    scenario_params: dict[str, Any] | None
    duration_s: float | None
    plugin_sinks: list[Any]
    mavlink: Any


def _plan(opts: RunOptions, path: Path, registry: Registry) -> _RunPlan:
    """Loads the profile and checks every name, setting and input file against it; prints
    the run's first line and calibrates an emulated board first when its profile asks."""
    profile = load_profile(path, registry)
    frame = opts.output_frame or profile.output_frame
    emulate = profile.emulation.scenario if opts.emulate is None and opts.emulated \
        else opts.emulate
    web = parse_bind(opts.web) if opts.web is not None else None
    if emulate is not None:
        registry.scenarios.get(emulate)  # an unknown name fails here, before any output
    scenario_params = _replay_params(opts, emulate)
    duration = opts.duration
    if duration is None and emulate is not None and scenario_params is None:
        duration = registry.scenarios.get(emulate).default_duration_s
    # checked before the board is opened
    plugin_sinks = opts.plugin_sinks(registry, board=profile.name,
                                     outputs=profile.outputs.plugin_sections(), frame=frame)
    mavlink = mavlink_sink(registry, opts, profile)  # a socket only: nothing sent yet
    _check_flight_outputs(opts, profile)  # opened after the calibration; mistakes found now
    where = f"emulated, scenario '{emulate}'" if emulate else "real hardware"
    print(f"imuhal {__version__}: {profile.name} ({where}) from {path}", file=sys.stderr)
    profile, text, note = _user_calibration(opts, path, profile, emulate, registry)
    from imuhal.calibrate.as_user import default_learning_notes

    for line in default_learning_notes(profile, registry):
        print(f"note: {line}", file=sys.stderr)
    # Real buses always run in real time; a dashboard of an emulated run is watched live.
    return _RunPlan(path=path, profile=profile, profile_text=text, calibrated_note=note,
                    frame=frame, emulate=emulate, web=web,
                    realtime=opts.realtime or emulate is None or web is not None,
                    scenario_params=scenario_params, duration_s=duration,
                    plugin_sinks=plugin_sinks, mavlink=mavlink)


def _learned(pipeline: Any) -> dict[str, Any]:
    """The calibrations learned in flight that converged, by device."""
    return {n: d.calibration for n, d in pipeline.devices.items()
            if d.calibration is not None and (
                (d.mag_learner is not None and d.mag_learner.converged)
                or (d.accel_teacher is not None and any(d.accel_teacher.learner.learned_axes)))}


class _RunSession:
    """One run's outputs and its recording: opened in order around the pipeline, closed by
    the caller's exit stack, reported at the end."""

    def __init__(self, opts: RunOptions, plan: _RunPlan) -> None:
        from imuhal.pipeline import ConsoleSink

        self.opts = opts
        self.plan = plan
        self.sinks: list[Any] = [] if opts.quiet else [ConsoleSink(sys.stdout,
                                                                   frame=plan.frame)]
        self.csv_sink: Any = None
        self.truth_sink: Any = None
        self.mcap: Any = None
        self.recorder: BusRecorder | None = None
        self.ended = "failed"  # how the run ended, for the recording's end mark

    def open(self, stack: contextlib.ExitStack, registry: Registry) -> Any:
        """The trace, the recording and the pipeline (hardware or emulated)."""
        from imuhal.emulation import open_emulated
        from imuhal.pipeline import Pipeline

        opts, plan = self.opts, self.plan
        trace = None
        if opts.trace:
            trace_file = AtomicFile(opts.trace, partial=True)
            # Committed even when opening the board fails: the trace of a failed probe is
            # exactly what a bug report needs.
            stack.callback(trace_file.commit)
            trace = _trace_writer(trace_file)
        if opts.record:
            recorder = self.recorder = BusRecorder(opts.record, run_header(
                plan.profile_text, str(plan.path), emulate=plan.emulate, seed=opts.seed))
            stack.callback(lambda: recorder.close(self.ended))
        if plan.emulate is None:
            pipeline = stack.enter_context(Pipeline.open(plan.profile, registry, trace=trace,
                                                         recorder=self.recorder))
        else:
            pipeline = stack.enter_context(open_emulated(
                plan.profile, registry, scenario=plan.emulate, realtime=plan.realtime,
                seed=opts.seed, trace=trace, recorder=self.recorder,
                scenario_params=plan.scenario_params))
        for w in pipeline.warnings:
            print(f"warning: {w}", file=sys.stderr)
        self._replay_duration(pipeline)
        return pipeline

    def _replay_duration(self, pipeline: Any) -> None:
        """A replay runs the rest of its record (opening the board took simulated time)."""
        from imuhal.emulation import EmulatedBoard

        if self.plan.emulate != "replay" or not isinstance(pipeline.board, EmulatedBoard):
            return
        left = pipeline.board.scenario.duration_s - pipeline.clock.now_ns() / 1e9  # type: ignore[attr-defined]  # the replay scenario (plan.emulate == "replay", tested above) has a duration
        asked = self.opts.duration
        if asked is not None and asked > left:
            print(f"warning: --replay-truth {self.opts.replay_truth} ends after {left:.3f} s; "
                  "the run stops there", file=sys.stderr)
        self.plan.duration_s = left if asked is None else min(asked, left)

    def add_outputs(self, stack: contextlib.ExitStack, pipeline: Any,
                    registry: Registry) -> None:
        """Every output sink, in the order they see each event."""
        from imuhal.emulation import EmulatedBoard, TruthSink
        from imuhal.pipeline import CsvSink

        opts, plan = self.opts, self.plan
        if plan.web is not None:
            self._add_live_view(stack, pipeline)
        if opts.output:
            self.csv_sink = CsvSink(opts.output, include_samples=opts.samples,
                                    frame=plan.frame)
            self.sinks.append(self.csv_sink)
        self.sinks.extend(_flight_sinks(opts, plan.profile, registry, stack))
        if opts.mcap:
            self.mcap = mcap_sink(registry, opts.mcap, plan.profile)
            self.sinks.append(self.mcap)
        if plan.mavlink is not None:
            stack.callback(plan.mavlink.close)  # also when the run fails before it starts
            self.sinks.append(plan.mavlink)
        if opts.truth:
            self.truth_sink = TruthSink(opts.truth, EmulatedBoard.of(pipeline).scenario,
                                        include_samples=opts.samples)
            self.sinks.append(self.truth_sink)
        self.sinks.extend(plan.plugin_sinks)
        describe_sinks(plan.plugin_sinks)
        if plan.calibrated_note:  # once every output is open: a mistake stays a one-line error
            print(plan.calibrated_note, file=sys.stderr)

    def _add_live_view(self, stack: contextlib.ExitStack, pipeline: Any) -> None:
        from imuhal.emulation import EmulatedBoard

        web = self.plan.web
        truth = pipeline.board if isinstance(pipeline.board, EmulatedBoard) else None
        live = stack.enter_context(LiveView(pipeline, truth=truth, host=web.host,
                                            port=web.port))
        self.sinks.append(live.sink)
        print(f"live view: {live.url}" + ("" if web.loopback else
              " (reachable from the network at this machine's address: read-only, "
              "no password; docs/live-view.md)"), file=sys.stderr)
        if live.exposure:
            print(f"warning: {live.exposure}", file=sys.stderr)

    def run(self, pipeline: Any) -> Any:
        """Runs the pipeline into the sinks; the run's summary (a stopped run's too)."""
        output = self.opts.output
        wall0 = time.perf_counter()
        try:
            summary = pipeline.run(self.plan.duration_s, self.sinks)
            self.ended = "complete"
        except RecordingWriteFailed as exc:
            raise ImuhalError(f"{exc}; the run stopped (the recording keeps what was "
                              f"flushed){_kept_note(output, self.csv_sink)}") from None
        except KeyboardInterrupt as stop:
            summary = self._stopped(pipeline, wall0, stop)
        except ImuhalError as exc:
            raise ImuhalError(f"{exc}{_kept_note(output, self.csv_sink)}") from exc
        except Exception:
            if output:
                print(f"imuhal: note{_kept_note(output, self.csv_sink)}", file=sys.stderr)
            raise
        return summary

    def _stopped(self, pipeline: Any, wall0: float, stop: KeyboardInterrupt) -> Any:
        """What ran until the stop, not the zeros of a summary taken out of a run."""
        summary = pipeline.summary(wall_s=time.perf_counter() - wall0,
                                   simulated_s=pipeline.span_s)
        summary.sinks = sink_counts(self.plan.plugin_sinks)  # pipeline.run closed them
        self.ended = "interrupted"
        why = f"stopped by {stop}" if str(stop) else "interrupted"
        print(f"\n{why}; the files are complete up to here", file=sys.stderr)
        return summary

    def check_log(self) -> None:
        """The log itself failed during the run (disk full, ...) and was aborted while the
        other outputs went on: a one-line error saying which file was kept."""
        if self.csv_sink is not None and not self.csv_sink.committed:
            raise ImuhalError(f"the log failed during the run (its warning is above)"
                              f"{_kept_note(self.opts.output, self.csv_sink)}")

    def report(self) -> None:
        """The closing lines: what each output wrote."""
        opts = self.opts
        lines: list[str] = []
        if self.csv_sink is not None:
            lines.append(f"wrote {self.csv_sink.rows} rows to {opts.output}")
        if self.mcap is not None:
            lines.append(report_mcap(self.mcap, str(opts.mcap)))
        if self.plan.mavlink is not None:
            lines.append(report_mavlink(self.plan.mavlink, str(opts.mavlink)))
        if self.truth_sink is not None:
            lines.append(f"wrote {self.truth_sink.rows} truth rows to {opts.truth}")
        lines += [f"wrote {sink.b_records} B records to {sink.path}" if sink.path else
                  "IGC log: no GNSS fix in the run, nothing written"
                  for sink in self.sinks if getattr(sink, "name", None) == "igc"]
        if self.recorder is not None:
            lines.append(f"recorded {self.recorder.transfers} bus transactions to "
                         f"{opts.record}")
        for line in lines:
            print(line, file=sys.stderr)


def _user_calibration(opts: RunOptions, path: Path, profile: Any,
                      emulate: str | None, registry: Registry) -> tuple[Any, str, str]:
    """The profile to run, its text and the line saying it was calibrated first (empty:
    it was not): an emulated board with sensor errors is calibrated first where its profile
    lacks a record (unless --skip-calibration); otherwise each missing record is named once,
    with what it may cost (imuhal.calibrate.as_user)."""
    from imuhal.calibrate.as_user import calibrate_emulated, missing_calibration_notes

    text = path.read_text(encoding="utf-8")
    if emulate is not None and not profile.emulation.sensor_errors:
        return profile, text, ""  # ideal chips: nothing to calibrate, nothing it costs
    if emulate is not None and not opts.skip_calibration:
        run = calibrate_emulated(profile, text, str(path), registry, seed=opts.seed)
        seed = profile.emulation.seed if opts.seed is None else opts.seed
        return run.profile, run.text, run.describe(seed) if run.measured else ""
    for note in missing_calibration_notes(profile, registry):
        print(f"note: {note}", file=sys.stderr)
    return profile, text, ""


def _save_learned(output: str, text: str, path: Path, learned: dict[str, Any],
                  registry: Registry) -> None:
    """--save-learned: the profile with what was learned in flight, or why nothing was."""
    from imuhal.calibrate.as_user import save_learned

    if not learned:
        print(f"nothing learned in flight to save: {output} not written (a device needs "
              "no stored record, learning not turned off, and enough turns; "
              "docs/calibration.md)",
              file=sys.stderr)
        return
    save_learned(text, str(path), output, learned, registry)
    print(f"wrote the profile with the calibration learned in flight ({', '.join(learned)}) "
          f"to {output}", file=sys.stderr)


def _flight_sinks(opts: RunOptions, profile: Any, registry: Registry,
                  stack: contextlib.ExitStack) -> list[Any]:
    """The --nmea outputs and the --audio / --audio-wav sink (the plugins registered as
    ``nmea`` and ``vario-audio``), closed with the run."""
    from imuhal.sinks.flight.transports import PtyTransport

    out: list[Any] = []
    sentences = _nmea_sentences(opts)
    extra: dict[str, Any] = {} if sentences is None else {"sentences": sentences}
    nmea = registry.sinks.get("nmea")
    for spec in opts.nmea:
        if spec.partition(":")[0] == "ble" and "sentences" not in extra:
            from imuhal.sinks.flight.ble import BLE_SENTENCES

            sink = nmea({"output": spec, "sentences": BLE_SENTENCES})
        else:
            sink = nmea({"output": spec, **extra})
        transport = sink.transport  # type: ignore[attr-defined]  # the sink registered as 'nmea' is a FlightSink, which has a transport
        where = transport.description
        stack.callback(_say_dropped, where, transport)  # after the close: it counts tails
        stack.callback(sink.close)
        if isinstance(transport, PtyTransport):
            where += f" (open {transport.path} in the flight app)"
        print(f"nmea: {where}", file=sys.stderr)
        exposure = getattr(transport, "exposure", None)
        if exposure:
            print(f"warning: {exposure}", file=sys.stderr)
        out.append(sink)
    if opts.audio or opts.audio_wav:
        out.append(registry.sinks.get("vario-audio")(
            {"curve": _audio_curve(opts, profile), "wav": opts.audio_wav,
             "live": opts.audio}))
    if opts.igc:
        log = profile.outputs.igc.model_copy(update={
            k: v for k, v in (("pilot", opts.igc_pilot), ("glider_type", opts.igc_glider))
            if v is not None})
        out.append(registry.sinks.get("igc")({
            "path": opts.igc, "log": log, "logger_type": f"imuhal,{profile.name}",
            "firmware": __version__,
            "device_drivers": {name: dev.driver for name, dev in profile.devices.items()}}))
    return out


def _nmea_sentences(opts: RunOptions) -> tuple[str, ...] | None:
    """The sentences --nmea-sentences names (None: each output's own)."""
    if opts.nmea_sentences is None:
        return None
    sentences = tuple(x.strip().upper() for x in opts.nmea_sentences.split(",") if x.strip())
    if not sentences:
        raise ImuhalError(f"--nmea-sentences {opts.nmea_sentences!r}: name at least one "
                          "sentence, e.g. --nmea-sentences LK8EX1,GGA")
    return sentences


def _check_flight_outputs(opts: RunOptions, profile: Any) -> None:
    """The --nmea, --nmea-sentences and --audio-* mistakes, found before the run starts
    (an emulated board's calibration takes seconds before its outputs are opened)."""
    from imuhal.sinks.flight import check_sentences, check_transport

    sentences = _nmea_sentences(opts)
    if sentences is not None:
        check_sentences(sentences, f"--nmea-sentences {opts.nmea_sentences}")
    for spec in opts.nmea:
        check_transport(spec)
    if opts.audio or opts.audio_wav:
        _audio_curve(opts, profile)


def _say_dropped(where: str, transport: Any) -> None:
    """Say at the end of the run how much an --nmea reader did not take, if anything."""
    if transport.dropped_bytes:
        print(f"nmea: {where}: {transport.dropped_bytes} bytes dropped, whole sentences the "
              "reader did not take in time", file=sys.stderr)


def _audio_curve(opts: RunOptions, profile: Any) -> Any:
    """The profile's audio curve with --audio-damping / --audio-sink-alarm applied."""
    from pydantic import ValidationError

    from imuhal.sinks.flight.audio import VarioAudioSettings

    update = {k: v for k, v in (("damping_s", opts.audio_damping),
                                ("sink_alarm_m_s", opts.audio_sink_alarm)) if v is not None}
    if not update:
        return profile.audio
    try:
        return VarioAudioSettings.model_validate({**profile.audio.model_dump(), **update})
    except ValidationError as exc:
        err = exc.errors()[0]
        if err["loc"] and err["loc"][0] == "damping_s":
            raise ImuhalError(f"--audio-damping {opts.audio_damping}: a time constant of "
                              "0 to 10 s, e.g. --audio-damping 1.5") from None
        raise ImuhalError(f"--audio-sink-alarm {opts.audio_sink_alarm}: "
                          f"{err['msg'].removeprefix('Value error, ')}") from None


def _trace_writer(out: AtomicFile, every_s: float = 2.0) -> Callable[[Any], None]:
    """Writes each bus transaction as a line, syncing ``out`` every ``every_s`` seconds of
    wall time like the CSV log (a power cut loses at most that much of the trace)."""
    last = time.monotonic()

    def write(transfer: Any) -> None:
        nonlocal last
        out.write(format_transfer(transfer) + "\n")
        now = time.monotonic()
        if now - last >= every_s:
            out.sync()
            last = now

    return write


def _kept_note(output: str | None, sink: Any) -> str:
    """What a failed run did to --output, for the end of its error message."""
    if not output:
        return ""
    if getattr(sink, "committed", False):  # another output failed after the log was closed
        return f"; {output} is complete ({sink.rows} rows)"
    partial = getattr(sink, "partial_path", None)
    if partial is not None:
        return (f"; {output} was left as it was and the {sink.rows} rows written before the "
                f"failure are in {partial}")
    return f"; nothing was written to {output}"


def _replay_params(opts: RunOptions, emulate: str | None) -> dict[str, Any] | None:
    """Scenario parameters from --replay-truth; the replay scenario cannot run without one."""
    if emulate == "replay":
        if not opts.replay_truth:
            raise ImuhalError("--emulate replay needs the truth CSV to fly: add --replay-truth "
                              "FILE.csv (e.g. one written by `imuhal run --truth`)")
        _check_replay_file(opts.replay_truth)
        return {"path": opts.replay_truth}
    if opts.replay_truth:
        raise ImuhalError("--replay-truth is read by the replay scenario; add --emulate replay")
    return None


MAX_REPLAY_S = 1e6
"""Longest record --replay-truth accepts (11.6 days): beyond it, a time column is wrong."""


def _check_replay_file(path: str) -> None:
    """A truth CSV that the replay scenario can fly, or one line saying what is wrong."""
    from imuhal.sim.truth_csv import read_truth_csv

    try:
        cols, _ = read_truth_csv(path)
    except FileNotFoundError:
        raise ImuhalError(f"--replay-truth {path}: file not found") from None
    except (OSError, UnicodeDecodeError, ValueError) as exc:
        raise ImuhalError(f"--replay-truth {path}: not a truth CSV ({exc}); give a file "
                          "written by `imuhal run --truth` (docs/simulation.md)") from None
    needed = ("t_s", "qw", "qx", "qy", "qz", "pn_m", "pe_m", "pd_m")
    missing = [c for c in needed if c not in cols]
    if missing:
        raise ImuhalError(f"--replay-truth {path}: missing column(s) {', '.join(missing)}; "
                          "give a file written by `imuhal run --truth` (docs/simulation.md)")
    t = cols["t_s"]
    if len(t) < 2:
        raise ImuhalError(f"--replay-truth {path}: needs at least two rows to fly")
    for name in needed:
        bad = [i for i, v in enumerate(cols[name]) if not math.isfinite(v)]
        if bad:
            raise ImuhalError(f"--replay-truth {path}: data row {bad[0] + 1}, column "
                              f"'{name}': not a finite number")
    if t[0] < 0 or t[-1] > MAX_REPLAY_S:
        raise ImuhalError(f"--replay-truth {path}: times run from {t[0]:g} to {t[-1]:g} s; "
                          f"they must lie between 0 and {MAX_REPLAY_S:g} s")
    steps = [i for i in range(1, len(t)) if t[i] <= t[i - 1]]
    if steps:
        raise ImuhalError(f"--replay-truth {path}: data row {steps[0] + 1}: time {t[steps[0]]:g}"
                          " s does not increase; rows must be in time order")
