"""``imuhal estimate NAME INPUT.csv --output OUT.csv``: run an estimator over a log."""

from __future__ import annotations

import argparse
import itertools
import sys
from pathlib import Path
from typing import Any

from imuhal.cli import args as types
from imuhal.cli.frame_option import frame_argument
from imuhal.cli.robot_outputs import add_mcap_argument, report_mcap
from imuhal.cli.sink_options import (
    SinkOptions,
    add_sink_arguments,
    describe_sinks,
    report_sinks,
)
from imuhal.core.atomic import check_outputs
from imuhal.core.conventions import CONVENTIONS, NED
from imuhal.core.errors import ImuhalError
from imuhal.core.samples import PressureSample
from imuhal.offline.csv_input import iter_sample_chunks
from imuhal.offline.csv_output import ColumnError, EstimateCsvWriter
from imuhal.offline.frames import resolve_input_frame, table_to_ned
from imuhal.offline.log_streams import bind_to_log, sample_streams, table_streams
from imuhal.offline.run_log import is_run_log, read_run_log
from imuhal.offline.runner import iter_offline, run_offline_samples
from imuhal.offline.settings_args import build_settings, parse_set_arguments
from imuhal.plugins.manager import Registry

AHRS_DEFAULT = "madgwick"
"""The --ahrs that gravity-compensates full IMU input to a vario filter."""

HELP = """\
INPUT is a log of `imuhal run --output LOG.csv --samples` (one row per event; flagged
samples are skipped) or a wide CSV with one row per time.
Wide input columns (project units and frames; see docs/units-and-frames.md):
  attitude estimators: t_s, gx_rad_s, gy_rad_s, gz_rad_s, ax_m_s2, ay_m_s2, az_m_s2
                       [, mx_ut, my_ut, mz_ut]   (accel = specific force, NED body:
                       a level board at rest reads az_m_s2 = -9.81)
  vario filters:       t_s, altitude_m, accel_up_m_s2 (either cell may be empty: a
                       multi-rate log carries on each row what was measured then)
                       or the attitude columns plus pressure_pa (imuhal runs --ahrs
                       and does the gravity compensation)
Other conventions: --input-frame NAME reads the gyro, accel and mag columns in that
convention's body axes and accelerometer sign (enu/ros: forward-left-up, specific force;
android: right-forward-up, specific force; win8: right-forward-up, gravity positive;
aerospace: forward-right-down, gravity positive). --output-frame NAME writes the quaternion
(body -> that earth frame) and that convention's Euler angles, with the name as a column
suffix (qw_enu ...); input columns named that way (ax_m_s2_enu ...) need no --input-frame.
Estimators always run in ned. See docs/units-and-frames.md.
Settings are the estimator's own fields: --set beta=0.1 --set accel_gate_g=0.6,1.4
(--set preset=reference: the reference implementation's values); --ahrs-set sets those of
the --ahrs estimator behind a vario filter.
"""


def add_parser(sub: Any) -> None:
    p = sub.add_parser(
        "estimate", help="run an estimator over a run log or a CSV of samples",
        description="Run any registered estimator over a log of `imuhal run --samples` or a "
        "wide CSV of samples.",
        epilog=HELP, formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("name", help="estimator name (see `imuhal plugins`)")
    p.add_argument("input", metavar="INPUT.csv")
    p.add_argument("--output", "-o", metavar="OUT.csv", required=True)
    p.add_argument("--set", dest="settings", action="append", default=[], metavar="KEY=VALUE",
                   help="an estimator setting (repeatable)")
    p.add_argument("--rate", type=types.rate_hz, metavar="HZ",
                   help="sample rate, when the input has no t_s column")
    p.add_argument("--ahrs", default=AHRS_DEFAULT, metavar="NAME",
                   help="attitude estimator for gravity compensation of full IMU input to a "
                   "vario filter (default: madgwick)")
    p.add_argument("--ahrs-set", dest="ahrs_settings", action="append", default=[],
                   metavar="KEY=VALUE", help="a setting of the --ahrs estimator (repeatable)")
    p.add_argument("--input-frame", type=frame_argument, metavar="NAME",
                   help="convention of the input's gyro/accel/mag columns: "
                   f"{', '.join(CONVENTIONS)} (ros = enu; default: the columns' frame "
                   "suffix, e.g. ax_m_s2_enu, else ned)")
    p.add_argument("--output-frame", type=frame_argument, default=NED, metavar="NAME",
                   help="convention of the output's attitude columns (default: ned)")
    p.add_argument("--columns", metavar="A,B,...",
                   help="write only these output columns, in this order (e.g. "
                   "t_s,qw,qx,qy,qz); default: every estimate and diagnostics column")
    add_mcap_argument(p)
    add_sink_arguments(p)
    p.add_argument("--frame-id", default="base_link", metavar="NAME",
                   help="with --mcap: header.frame_id of the messages (default: base_link)")
    p.set_defaults(func=cmd_estimate)


def _column_list(text: str | None) -> list[str] | None:
    if text is None:
        return None
    names = [c.strip() for c in text.split(",") if c.strip()]
    if not names:
        raise ColumnError("--columns: give at least one column name, e.g. --columns t_s,qw,qx,"
                         "qy,qz")
    twice = sorted({c for c in names if names.count(c) > 1})
    if twice:
        raise ColumnError(f"--columns: {', '.join(twice)} named twice; name each column once")
    return names


def cmd_estimate(args: argparse.Namespace, registry: Registry) -> int:
    check_outputs({"--output": args.output, "--mcap": args.mcap}, {"INPUT.csv": args.input})
    run_log = is_run_log(args.input)
    est_cls = registry.estimators.get(args.name)
    _check_combinations(args, run_log, est_cls)
    settings = build_settings(est_cls.Settings, parse_set_arguments(args.settings), args.name)
    estimator = est_cls(settings)
    ahrs_cls = registry.estimators.get(args.ahrs)
    ahrs_settings = build_settings(ahrs_cls.Settings,
                                   parse_set_arguments(args.ahrs_settings, "--ahrs-set"),
                                   args.ahrs, "--ahrs-set")
    columns = _column_list(args.columns)
    writer = EstimateCsvWriter(args.output, args.output_frame, columns)
    mcap = None
    plugin_sinks: list[Any] = []
    try:
        # checked before the input is read; the board (the topics' name) is the input log's
        # unless --sink-set NAME.board says otherwise
        plugin_sinks += SinkOptions.from_args(args).plugin_sinks(
            registry, board=Path(args.input).stem, outputs={}, frame=args.output_frame)
        describe_sinks(plugin_sinks)
        if run_log:
            # A run log is read whole: its rows are events of many kinds, and the samples are
            # rebuilt in the pipeline's order.
            log = read_run_log(args.input, args.input_frame)
            ahrs = _gravity_ahrs(args, ahrs_cls, ahrs_settings, True)
            _bind(estimator, ahrs, sample_streams(log.samples))
            estimates = run_offline_samples(estimator, log.samples, ahrs=ahrs)
            writer.write(estimates)
            events: list[Any] = [*log.samples, *estimates]
            events.sort(key=lambda e: e.t_ns)  # stable: a sample before the estimates it led to
            if args.mcap:
                mcap = _write_mcap(args, registry, events)
            for sink in plugin_sinks:
                for event in events:
                    sink.handle(event)
            read = (f"{log.rows} log rows ({len(log.samples)} valid samples, {log.flagged} "
                    "flagged skipped)")
        else:
            # the log is read, run and written one chunk at a time: memory stays flat in its
            # length
            chunks = (table_to_ned(*resolve_input_frame(t, args.input_frame))
                      for t in iter_sample_chunks(args.input, rate_hz=args.rate))
            first = next(chunks)
            ahrs = _gravity_ahrs(args, ahrs_cls, ahrs_settings,
                                 "altitude_m" not in first.columns)
            _bind(estimator, ahrs, table_streams(first))
            n_in = 0
            for table in itertools.chain([first], chunks):
                n_in += len(table)
                writer.write(next(iter_offline(estimator, [table], ahrs=ahrs, columnar=True)))
            read = f"{n_in} input rows"
            if n_in and not writer.rows:
                raise ImuhalError(_nothing_estimated(args, est_cls, first.columns, n_in))
        rows = writer.commit()
        if mcap is not None:
            mcap.close()
    except BaseException:
        writer.abort()
        if mcap is not None:
            mcap.abort()
        raise
    finally:
        for sink in plugin_sinks:  # a broker keeps what it was handed, also after a failure
            sink.close()
    print(f"{args.name}: {read} -> {rows} estimates in {args.output}", file=sys.stderr)
    if mcap is not None:
        print(report_mcap(mcap, args.mcap), file=sys.stderr)
    report_sinks(plugin_sinks)
    for est in (estimator, ahrs):
        if est is not None:
            _report_rejected(est)
    return 0


def _check_combinations(args: argparse.Namespace, run_log: bool, est_cls: Any) -> None:
    """Options that the input's kind or the estimator would silently ignore."""
    streamed = f"--mcap {args.mcap}" if args.mcap else SinkOptions.from_args(args).sink_option()
    if streamed and not run_log:
        raise ImuhalError(f"{streamed}: needs a run log as INPUT (imuhal run --output "
                          "LOG.csv --samples), whose samples name their devices; "
                          f"{args.input} is a wide CSV")
    if args.rate is not None and run_log:
        raise ImuhalError(f"{args.input}: a run log has its own times (t_s); --rate is for a "
                          "wide CSV without them - drop --rate")
    if PressureSample not in est_cls.consumes and (args.ahrs_settings or
                                                   args.ahrs != AHRS_DEFAULT):
        option = "--ahrs-set" if args.ahrs_settings else "--ahrs"
        raise ImuhalError(f"{option} configures the attitude estimator behind a vario filter; "
                          f"{args.name} is not one - drop {option} (settings of {args.name} "
                          "go in --set)")


def _bind(estimator: Any, ahrs: Any, streams: Any) -> None:
    """Bind the estimators to the stream measured from the log (rates follow the data; a
    --set or --ahrs-set rate that contradicts it is an error)."""
    bind_to_log(estimator, streams, "--set")
    if ahrs is not None:
        bind_to_log(ahrs, streams, "--ahrs-set")


def _write_mcap(args: argparse.Namespace, registry: Registry, events: list[Any]) -> Any:
    """The run log's samples and the new estimates, in time order (a sample before the
    estimates it led to), handed to the ``mcap`` sink; the caller closes it."""
    from imuhal import __version__

    sink = registry.sinks.get("mcap")({
        "path": args.mcap, "ros": {"frame_id": args.frame_id},
        "metadata": {"input": str(args.input), "estimator": args.name,
                     "imuhal_version": __version__}})
    for event in events:
        sink.handle(event)
    return sink


def _gravity_ahrs(args: argparse.Namespace, ahrs_cls: Any, settings: Any, needed: bool
                  ) -> Any:
    """The --ahrs estimator a vario filter fed IMU samples needs (None when it does not)."""
    if not needed or args.name == args.ahrs:
        return None
    if any(t.__name__ == "PressureSample" for t in ahrs_cls.consumes):
        return None
    return ahrs_cls(settings)


def _report_rejected(estimator: Any) -> None:
    """Say how many input values no sensor could have reported were dropped, if any."""
    counts = estimator.diagnostics().get("beyond_full_scale")
    if not counts:
        return
    if isinstance(counts, dict):
        parts = [f"{n} {channel}" for channel, n in counts.items() if n]
    else:
        parts = [f"{counts} gyro/accel"]
    if parts:
        print(f"{estimator.name}: dropped {', '.join(parts)} value(s) beyond the full scale "
              "(not fused; see the gyro_full_scale_rad_s / accel_full_scale_m_s2 settings)",
              file=sys.stderr)


def _nothing_estimated(args: argparse.Namespace, est_cls: Any, columns: Any, rows: int) -> str:
    """The one line for an estimator that made no estimate from a CSV with rows: what it
    takes beside what the CSV has (a 9-DOF filter on a CSV without magnetometer columns)."""
    takes = ", ".join(t.__name__.removesuffix("Sample").lower()
                      for t in getattr(est_cls, "consumes", ()))
    return (f"{args.input}: {args.name} made no estimate from {rows} rows: it takes "
            f"{takes or 'other inputs'}, and the CSV has columns {', '.join(map(str, columns))}"
            f"; give the columns it needs (docs/estimators.md) or choose another estimator")
