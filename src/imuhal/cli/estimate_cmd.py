"""``imuhal estimate NAME INPUT.csv --output OUT.csv``: run an estimator over a log."""

from __future__ import annotations

import argparse
import sys
from typing import Any

from imuhal.offline.csv_input import read_sample_csv
from imuhal.offline.csv_output import write_estimates
from imuhal.offline.run_log import is_run_log, read_run_log
from imuhal.offline.runner import run_offline, run_offline_samples
from imuhal.offline.settings_args import build_settings, parse_set_arguments
from imuhal.plugins.manager import Registry

HELP = """\
INPUT is a log of `imuhal run --output LOG.csv --samples` (one row per event; flagged
samples are skipped) or a wide CSV with one row per time.
Wide input columns (project units and frames; see docs/units-and-frames.md):
  attitude estimators: t_s, gx_rad_s, gy_rad_s, gz_rad_s, ax_m_s2, ay_m_s2, az_m_s2
                       [, mx_ut, my_ut, mz_ut]   (accel = specific force, NED body:
                       a level board at rest reads az_m_s2 = -9.81)
  vario filters:       t_s, altitude_m, accel_up_m_s2
                       or the attitude columns plus pressure_pa (imuhal runs --ahrs
                       and does the gravity compensation)
Settings are the estimator's own fields: --set beta=0.1 --set accel_gate_g=0.6,1.4
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
    p.add_argument("--rate", type=float, metavar="HZ",
                   help="sample rate, when the input has no t_s column")
    p.add_argument("--ahrs", default="madgwick", metavar="NAME",
                   help="attitude estimator for gravity compensation of full IMU input to a "
                   "vario filter (default: madgwick)")
    p.set_defaults(func=cmd_estimate)


def cmd_estimate(args: argparse.Namespace, registry: Registry) -> int:
    est_cls = registry.estimators.get(args.name)
    settings = build_settings(est_cls.Settings, parse_set_arguments(args.settings), args.name)
    estimator = est_cls(settings)
    if is_run_log(args.input):
        log = read_run_log(args.input)
        outputs = run_offline_samples(estimator, log.samples,
                                      ahrs=_gravity_ahrs(args, registry, True))
        read = (f"{log.rows} log rows ({len(log.samples)} valid samples, {log.flagged} "
                "flagged skipped)")
    else:
        table = read_sample_csv(args.input, rate_hz=args.rate)
        ahrs = _gravity_ahrs(args, registry, "altitude_m" not in table.columns)
        outputs = run_offline(estimator, table, ahrs=ahrs)
        read = f"{len(table)} input rows"
    rows = write_estimates(args.output, outputs)
    print(f"{args.name}: {read} -> {rows} estimates in {args.output}", file=sys.stderr)
    return 0


def _gravity_ahrs(args: argparse.Namespace, registry: Registry, needed: bool) -> Any:
    """The --ahrs estimator a vario filter fed IMU samples needs (None when it does not)."""
    if not needed or args.name == args.ahrs:
        return None
    ahrs_cls = registry.estimators.get(args.ahrs)
    if any(t.__name__ == "PressureSample" for t in ahrs_cls.consumes):
        return None
    return ahrs_cls()
