"""docs/scripts/flight_benchmark.py: how it states issue 10's targets (no flight flown here).

The full benchmark takes minutes (docs/estimators.md); these check the table of targets it
writes: every installed AHRS is measured, a target missed by one AHRS is a gap naming it and
its excess, and the vario targets are judged on the seed profile's chain (behind madgwick).
"""

from __future__ import annotations

from tests.support.docs_scripts import load_docs_script

from imuhal.plugins.manager import load_registry

fb = load_docs_script("flight_benchmark")
MET = {"thermal_nominal_deg": 0.6, "thermal_velocity_deg": 0.9, "climb_thermal_m_s": 0.04,
       "climb_rest_m_s": 0.024, "step_delay_s": 0.02, "upside_down_s": 0.0, "rc_max_deg": 3.6}


def _status(per_ahrs: dict[str, dict[str, float]]) -> dict[str, list[str]]:
    res = fb.Results(per_ahrs=per_ahrs)
    rows = fb.target_status(res)
    assert len(rows) == len(fb.STATUS_ROWS) == len(fb.TARGETS)
    return {key: row for (key, *_), row in zip(fb.STATUS_ROWS, rows, strict=True)}


def test_every_installed_ahrs_is_benchmarked() -> None:
    names = fb.installed_ahrs(load_registry())
    assert {"madgwick", "mahony", "imufilter", "freescale-9dof", "freescale-6dof",
            "decoupled"} <= set(names)


def test_targets_met_by_every_ahrs_say_so() -> None:
    status = _status({"madgwick": MET, "mahony": MET})
    assert status["rc_max_deg"][3] == "met by every AHRS"
    assert status["climb_rest_m_s"][3] == "met"


def test_a_target_missed_by_one_ahrs_is_a_gap_naming_it_and_its_excess() -> None:
    status = _status({"madgwick": MET, "decoupled": {**MET, "rc_max_deg": 42.7}})
    row = status["rc_max_deg"]
    assert "met by 1 of 2" in row[3]
    assert "**gap**: decoupled 42.70 (+32.70)" in row[3]
    assert row[2] == "worst 42.70 (decoupled)"


def test_vario_targets_are_judged_behind_the_seed_profiles_madgwick() -> None:
    status = _status({"madgwick": {**MET, "climb_thermal_m_s": 0.06}, "mahony": MET})
    assert status["climb_thermal_m_s"][3].startswith("**gap** 0.010")
    status = _status({"madgwick": MET, "mahony": {**MET, "climb_thermal_m_s": 0.056}})
    assert status["climb_thermal_m_s"][3] == "met; over it behind other AHRS: mahony 0.056"
