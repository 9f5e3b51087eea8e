"""The Python examples of docs/estimators.md, docs/simulation.md and docs/reliability.md run
as written (the README's and docs/recording.md's have their own tests), and every fault kind
the profile accepts is documented once in docs/reliability.md's fault model."""

from __future__ import annotations

import contextlib
import io
import math
import re
from pathlib import Path

import pytest

from imuhal.profile.faults import FAULT_KINDS

ROOT = Path(__file__).resolve().parents[2]


def _python_blocks(page: str) -> list[str]:
    return re.findall(r"```python\n(.*?)```", (ROOT / "docs" / page).read_text(), flags=re.S)


def _run(code: str, page: str, namespace: dict) -> str:
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        exec(compile(code, f"docs/{page}", "exec"), namespace)
    return out.getvalue()


@pytest.fixture
def in_tmp_with_profiles(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    (tmp_path / "profiles").symlink_to(ROOT / "profiles")
    monkeypatch.chdir(tmp_path)  # the examples name profiles/... and write run/truth.csv
    return tmp_path


def test_the_estimator_examples_run_one_after_the_other_and_chain_offline(
        in_tmp_with_profiles: Path) -> None:
    namespace: dict = {}
    direct, chained = _python_blocks("estimators.md")[:2]
    printed = _run(direct, "estimators.md", namespace).splitlines()
    assert len(printed) == 2  # one attitude, one vertical estimate
    _run(chained, "estimators.md", namespace)
    climb = namespace["climb"]
    assert len(climb) > 100 and all(math.isfinite(c) for c in climb)


def test_the_simulation_examples_feed_an_emulator_and_record_a_truth_file(
        in_tmp_with_profiles: Path) -> None:
    (in_tmp_with_profiles / "run").mkdir()
    namespace: dict = {}
    using, truth = _python_blocks("simulation.md")[:2]
    _run(using, "simulation.md", namespace)
    _run(truth, "simulation.md", namespace)
    columns, metadata = namespace["columns"], namespace["metadata"]
    assert len(columns["t_s"]) == 15000 and metadata["scenario"] == "thermal"


def test_the_fault_injection_example_logs_the_faults_it_asked_for(
        in_tmp_with_profiles: Path) -> None:
    from imuhal.plugins import load_registry
    from imuhal.profile import load_profile

    registry = load_registry()
    namespace = {"registry": registry,  # as the README's embedding example makes them
                 "profile": load_profile("profiles/seed-paraglider-vario.yaml", registry)}
    (example,) = _python_blocks("reliability.md")
    _run(example, "reliability.md", namespace)
    injected = namespace["p"].board.faults.log.injected
    assert injected["baro"]["bus_errors"] > 0 and injected["imu"]["reset"] == 1


def test_every_fault_kind_has_one_row_in_the_fault_model_table() -> None:
    text = (ROOT / "docs/reliability.md").read_text()
    table = text.split("## The fault model\n", 1)[1].split("\n\n", 2)[1]
    rows = re.findall(r"^\| `(\w+)` \|", table, flags=re.M)
    kinds = [k.model_fields["kind"].default for k in FAULT_KINDS]
    assert sorted(rows) == sorted(kinds)


def test_the_estimators_section_shown_for_the_seed_board_is_the_bundled_profiles() -> None:
    import yaml

    shown = re.findall(r"```yaml\n(.*?)```", (ROOT / "docs/estimators.md").read_text(),
                       flags=re.S)[0]
    bundled = yaml.safe_load((ROOT / "profiles/seed-paraglider-vario.yaml").read_text())
    assert yaml.safe_load(shown)["estimators"] == bundled["estimators"]
