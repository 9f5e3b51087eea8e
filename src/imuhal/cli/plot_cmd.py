"""``imuhal plot LOG.csv [--truth TRUTH.csv] -o FIGURE.png``: a run log as a figure."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

from imuhal.core.atomic import check_outputs
from imuhal.plugins.manager import Registry


def add_parser(sub: Any) -> None:
    p = sub.add_parser(
        "plot", help="plot a run log (attitude, altitude, climb, sensors, device health)",
        description="Plot a log of `imuhal run --output LOG.csv` (with --samples for the raw "
        "sensors and device health) or of `imuhal estimate`: attitude, altitude and climb "
        "rate, raw sensors, flagged samples and sample rates over time. With --truth, the "
        "truth is overlaid and the errors are shown. Needs matplotlib: "
        "pip install 'imuhal[plot]'.",
    )
    p.add_argument("log", metavar="LOG.csv")
    p.add_argument("--truth", metavar="TRUTH.csv",
                   help="a truth file of the same run (`imuhal run --truth`)")
    p.add_argument("--output", "-o", metavar="FIGURE.png", required=True,
                   help="the figure to write (.png, .pdf or .svg)")
    p.set_defaults(func=cmd_plot)


def cmd_plot(args: argparse.Namespace, registry: Registry) -> int:
    from imuhal.offline.plotting import plot_log, read_log, read_truth

    out = Path(args.output)
    # links and hard links too: the figure never replaces the log or the truth it shows
    check_outputs({"--output": args.output}, {"LOG.csv": args.log, "--truth": args.truth})
    log = read_log(args.log)
    truth = read_truth(args.truth) if args.truth else None
    figure = plot_log(log, truth)
    figure.save(out)
    print(f"wrote {out} ({', '.join(figure.axes)})", file=sys.stderr)
    return 0
