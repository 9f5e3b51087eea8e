"""docs/scripts/evaluation_tables.py --defaults: how it reads each estimator's BROAD rows
(synthetic results; the flight columns are flight_benchmark.py's, tested with it)."""

from __future__ import annotations

from tests.support.docs_scripts import load_docs_script

from imuhal.evaluate.runner import TrialResult

tables = load_docs_script("evaluation_tables")


def _row(label: str, dof: int, trial: int, total: float, inclination: float) -> TrialResult:
    return TrialResult(trial=f"{trial:02d}_x", groups=("all_trials",),
                       estimator=label.split()[0], label=label, dof=dof, total_deg=total,
                       heading_deg=total, inclination_deg=inclination, evaluated=100,
                       missing=0, seconds=0.1)


def test_a_mean_over_every_available_trial_is_printed_bare() -> None:
    rows = [_row("vqf", 9, i, 2.0 + (i % 2), 0.5) for i in range(tables.BROAD_TRIALS)]
    assert tables._broad_mean(rows, "vqf", 9, "total_deg") == "2.50"


def test_a_mean_over_fewer_trials_says_how_many() -> None:
    rows = [_row("vqf", 6, i, 90.0, 0.7) for i in range(3)]
    assert tables._broad_mean(rows, "vqf", 6, "inclination_deg") == "0.70 (3 trials)"


def test_only_the_defaults_label_counts_and_a_missing_one_is_a_dash() -> None:
    rows = [_row("vqf offline=true", 9, i, 1.0, 0.4) for i in range(tables.BROAD_TRIALS)]
    assert tables._broad_mean(rows, "vqf", 9, "total_deg") == "-"
    assert tables._broad_mean(rows, "vqf offline=true", 9, "total_deg") == "1.00"


def test_digits_can_be_asked_for_where_the_target_needs_them() -> None:
    # the 6-DOF inclination target is VQF's 0.723 deg: two digits would make 0.725 a tie
    rows = [_row("vqf", 6, i, 90.0, 0.7251) for i in range(tables.BROAD_TRIALS)]
    assert tables._broad_mean(rows, "vqf", 6, "inclination_deg", 3) == "0.725"
