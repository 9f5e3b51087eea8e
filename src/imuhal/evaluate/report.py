"""Aggregating trial results per group and overall, and writing them.

As in BROAD's ``getAveragedRmseValues``: a group's figure is the mean of its trials' RMSEs
(each trial counts once, whatever its length); "all" is the mean over every trial evaluated.
"""

from __future__ import annotations

import csv
import io
import json
import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from imuhal.core.atomic import AtomicFile
from imuhal.evaluate.runner import TrialResult

ALL = "all"
METRICS = ("total_deg", "heading_deg", "inclination_deg")


@dataclass(frozen=True)
class GroupResult:
    group: str
    label: str
    dof: int
    trials: int
    total_deg: float
    heading_deg: float
    inclination_deg: float


def _mean(values: list[float]) -> float:
    return float(np.mean(values)) if values else math.nan


def aggregate(results: Sequence[TrialResult]) -> list[GroupResult]:
    """Per (label, dof): the mean over all trials, then over each group's trials."""
    keys = list(dict.fromkeys((r.label, r.dof) for r in results))
    groups = list(dict.fromkeys(g for r in results for g in r.groups if g != "all_trials"))
    out: list[GroupResult] = []
    for label, dof in keys:
        rows = [r for r in results if (r.label, r.dof) == (label, dof)]
        for group in (ALL, *groups):
            sel = rows if group == ALL else [r for r in rows if group in r.groups]
            if not sel:
                continue
            out.append(GroupResult(group, label, dof, len(sel),
                                   *(_mean([getattr(r, m) for r in sel]) for m in METRICS)))
    return out


def summary_table(groups: Sequence[GroupResult], group: str = ALL) -> str:
    """A fixed-width table of one group: estimator rows, total/heading/inclination columns."""
    rows = [g for g in groups if g.group == group]
    width = max([len("estimator"), *(len(g.label) for g in rows)])
    lines = [f"{'estimator':<{width}}  dof  trials  total_deg  heading_deg  inclination_deg"]
    for g in rows:
        lines.append(f"{g.label:<{width}}  {g.dof:>3}  {g.trials:>6}  {g.total_deg:>9.2f}  "
                     f"{g.heading_deg:>11.2f}  {g.inclination_deg:>15.2f}")
    return "\n".join(lines)


def group_table(groups: Sequence[GroupResult], metric: str, dof: int) -> str:
    """Markdown: one row per estimator, one column per group, ``metric`` (deg) at ``dof``."""
    rows = [g for g in groups if g.dof == dof]
    names = list(dict.fromkeys(g.group for g in rows))
    labels = list(dict.fromkeys(g.label for g in rows))
    cell = {(g.label, g.group): g for g in rows}
    out = ["| estimator | " + " | ".join(names) + " |", "|---" * (len(names) + 1) + "|"]
    for label in labels:
        vals = [f"{getattr(cell[(label, n)], metric):.2f}" if (label, n) in cell else "-"
                for n in names]
        out.append(f"| {label} | " + " | ".join(vals) + " |")
    return "\n".join(out)


def markdown_report(groups: Sequence[GroupResult]) -> str:
    """The tables docs/evaluation.md shows: per DOF, total/heading/inclination by group."""
    parts = []
    for dof in sorted({g.dof for g in groups}, reverse=True):
        for metric in METRICS:
            name = metric.removesuffix("_deg")
            parts.append(f"**{dof}-DOF, {name} RMSE (deg), mean over the group's trials**\n\n"
                         + group_table(groups, metric, dof))
    return "\n\n".join(parts) + "\n"


def write_markdown(path: str | Path, groups: Sequence[GroupResult]) -> None:
    with AtomicFile(path) as f:
        f.write(markdown_report(groups))


def write_csv(path: str | Path, results: Sequence[TrialResult]) -> None:
    """One row per trial x setting x DOF (atomically)."""
    buf = io.StringIO()
    fields = list(results[0].as_row()) if results else ["trial"]
    w = csv.DictWriter(buf, fieldnames=fields, lineterminator="\n")
    w.writeheader()
    for r in results:
        w.writerow({k: (repr(v) if isinstance(v, float) else v) for k, v in r.as_row().items()})
    with AtomicFile(path, newline="") as f:
        f.write(buf.getvalue())


def to_json(results: Sequence[TrialResult], groups: Sequence[GroupResult]) -> dict[str, Any]:
    return {"trials": [r.as_row() for r in results],
            "groups": [g.__dict__ for g in groups]}


def write_json(path: str | Path, results: Sequence[TrialResult],
               groups: Sequence[GroupResult]) -> None:
    with AtomicFile(path) as f:
        json.dump(to_json(results, groups), f, indent=1, allow_nan=True)
