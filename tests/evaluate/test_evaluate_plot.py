"""``imuhal evaluate --plot``: the bars are the evaluation's errors (checked on the bar
heights, not on pixels), drawn by the one plotting module."""

from __future__ import annotations

import json

import numpy as np
import pytest

pytest.importorskip("h5py")
pytest.importorskip("matplotlib", reason="plots need the 'plot' extra (in the test extra)")

from tests.support.broad_synthetic import synthetic_trial, write_hdf5, write_trials_json

from imuhal.cli.main import main
from imuhal.evaluate.runner import TrialResult
from imuhal.offline.plotting import MEAN, plot_trial_errors


def _result(trial: str, label: str, dof: int, total: float, heading: float,
            inclination: float) -> TrialResult:
    return TrialResult(trial, ("all_trials",), label.split()[0], label, dof, total, heading,
                       inclination, 100, 0, 0.1)


def _bars(ax: object) -> dict[str, list[float]]:
    return {c.get_label(): [p.get_height() for p in c.patches]  # type: ignore[attr-defined]
            for c in ax.containers}  # type: ignore[attr-defined]


def test_each_panel_holds_every_estimators_error_per_trial_and_its_mean() -> None:
    results = [_result("t1", "madgwick", 9, 3.0, 2.0, 1.0),
               _result("t2", "madgwick", 9, 5.0, 4.0, 2.0),
               _result("t1", "vqf", 9, 1.0, 0.5, 0.25),
               _result("t2", "vqf", 9, 2.0, 1.5, 0.75),
               _result("t1", "madgwick", 6, 9.0, 9.0, 0.5),
               _result("t2", "madgwick", 6, 9.0, 9.0, 1.5)]
    fig = plot_trial_errors(results)
    assert list(fig.axes) == ["9-DOF total", "9-DOF heading", "9-DOF inclination",
                              "6-DOF inclination"]
    assert _bars(fig.axes["9-DOF total"]) == {"madgwick": [3.0, 5.0, 4.0],
                                              "vqf": [1.0, 2.0, 1.5]}
    assert _bars(fig.axes["9-DOF heading"])["vqf"] == [0.5, 1.5, 1.0]
    assert _bars(fig.axes["6-DOF inclination"]) == {"madgwick": [0.5, 1.5, 1.0]}
    ticks = [t.get_text() for t in fig.axes["9-DOF total"].get_xticklabels()]
    assert ticks == ["t1", "t2", MEAN]


def test_a_trial_an_estimator_was_not_run_on_has_no_bar() -> None:
    fig = plot_trial_errors([_result("t1", "vqf", 6, 1, 1, 0.5),
                             _result("t1", "mahony", 6, 1, 1, 2.0),
                             _result("t2", "mahony", 6, 1, 1, 4.0)])
    vqf = _bars(fig.axes["6-DOF inclination"])["vqf"]
    assert vqf[0] == 0.5 and np.isnan(vqf[1]) and vqf[2] == 0.5


def test_evaluate_plot_draws_the_results_it_writes(tmp_path, capsys) -> None:
    d = tmp_path / "broad"
    d.mkdir()
    write_hdf5(d / "01_a.hdf5", synthetic_trial(seconds=2.0, seed=1))
    write_hdf5(d / "02_b.hdf5", synthetic_trial(seconds=2.0, seed=2))
    write_trials_json(d, {"01_a": ["all_trials"], "02_b": ["all_trials"]})
    figure, out_json = tmp_path / "errors.png", tmp_path / "r.json"
    assert main(["evaluate", str(d), "-e", "madgwick", "-e", "madgwick:beta=0.1", "--dof",
                 "9", "-q", "--json", str(out_json), "--plot", str(figure)]) == 0
    assert figure.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    trials = json.loads(out_json.read_text())["trials"]
    results = [TrialResult(**{**r, "groups": tuple(r["groups"].split())}) for r in trials]
    bars = _bars(plot_trial_errors(results).axes["9-DOF total"])
    assert bars["madgwick beta=0.1"][:2] == [r["total_deg"] for r in trials
                                            if r["label"] == "madgwick beta=0.1"]


def test_evaluate_refuses_an_unknown_figure_format_before_evaluating(tmp_path, capsys) -> None:
    assert main(["evaluate", str(tmp_path / "none.hdf5"), "--plot",
                 str(tmp_path / "errors.jpeg")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "unknown figure format 'jpeg'" in err[0]
