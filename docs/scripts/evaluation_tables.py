"""The tables of docs/evaluation.md from ``imuhal evaluate --json`` outputs (several runs
merged, e.g. one per DOF).

    imuhal evaluate ~/.cache/imuhal/broad --dof 9 --dof 6 -e vqf ... --json run1.json
    python docs/scripts/evaluation_tables.py run1.json run2.json > tables.md
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "src"))

from imuhal.evaluate.report import aggregate, markdown_report, summary_table
from imuhal.evaluate.runner import TrialResult


def load(path: str) -> list[TrialResult]:
    rows = json.loads(Path(path).read_text())["trials"]
    return [TrialResult(**{**r, "groups": tuple(r["groups"].split())}) for r in rows]


def main() -> None:
    results = [r for p in sys.argv[1:] for r in load(p)]
    groups = aggregate(results)
    print("```\n" + summary_table(groups) + "\n```\n")
    print(markdown_report(groups))


if __name__ == "__main__":
    main()
