"""The tables of docs/evaluation.md from ``imuhal evaluate --json`` outputs (several runs
merged, e.g. one per DOF), and optionally their per-trial figure (the same figure as
``imuhal evaluate --plot``, drawn by imuhal.offline.plotting).

    imuhal evaluate ~/.cache/imuhal/broad --dof 9 --dof 6 -e vqf ... --json run1.json
    python docs/scripts/evaluation_tables.py run1.json run2.json > tables.md
    python docs/scripts/evaluation_tables.py run1.json run2.json --plot errors.png > tables.md
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "src"))

from imuhal.evaluate.report import aggregate, markdown_report, summary_table
from imuhal.evaluate.runner import TrialResult
from imuhal.offline.plotting import check_figure_path, plot_trial_errors


def load(path: str) -> list[TrialResult]:
    rows = json.loads(Path(path).read_text())["trials"]
    return [TrialResult(**{**r, "groups": tuple(r["groups"].split())}) for r in rows]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("results", nargs="+", metavar="RESULTS.json")
    parser.add_argument("--plot", metavar="FIGURE.png",
                        help="also draw every trial's errors (needs matplotlib)")
    args = parser.parse_args()
    if args.plot:
        check_figure_path(args.plot)
    results = [r for p in args.results for r in load(p)]
    groups = aggregate(results)
    print("```\n" + summary_table(groups) + "\n```\n")
    print(markdown_report(groups))
    if args.plot:
        plot_trial_errors(results, title="BROAD: RMSE per trial").save(args.plot)
        print(f"wrote {args.plot}", file=sys.stderr)


if __name__ == "__main__":
    main()
