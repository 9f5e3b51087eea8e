"""``imuhal run --emulate replay --replay-truth FILE`` flies a truth file ``run --truth`` wrote."""

from __future__ import annotations

import csv
from pathlib import Path

import pytest

from imuhal.cli.main import main
from imuhal.sim.recorded import RecordedMotion


def _rows(path: Path) -> list[dict[str, str]]:
    with path.open(newline="") as f:
        return list(csv.DictReader(line for line in f if not line.startswith("#")))


def test_a_truth_file_from_run_truth_is_flown_again(tmp_path: Path) -> None:
    truth, first, again = tmp_path / "truth.csv", tmp_path / "a.csv", tmp_path / "b.csv"
    assert main(["run", "profiles/seed-rc-vario.yaml", "--emulate", "rc-flight", "--duration",
                 "12", "--quiet", "--output", str(first), "--truth", str(truth)]) == 0
    assert float(_rows(truth)[0]["t_s"]) > 0  # starts at the first estimate, not at 0
    assert main(["run", "profiles/seed-rc-vario.yaml", "--emulate", "replay",
                 "--replay-truth", str(truth), "--quiet", "--output", str(again)]) == 0
    true_alt = {round(float(r["t_s"]), 6): float(r["altitude_m"]) for r in _rows(truth)}
    vario = [r for r in _rows(again) if r["kind"] == "vertical"]
    assert float(vario[-1]["t_s"]) > 11.0  # flown to the end of the file
    # The estimate is above the pressure reference, the truth above the origin: compare the
    # height gained since t = 5 s.
    pairs = [(float(r["altitude_m"]), true_alt[float(r["t_s"])]) for r in vario
             if float(r["t_s"]) in true_alt and float(r["t_s"]) > 5]
    assert len(pairs) > 100
    (est0, true0) = pairs[0]
    assert max(abs(est - est0 - (true - true0)) for est, true in pairs) < 2.0
    assert max(abs(true - true0) for _, true in pairs) > 5.0  # the flight does climb


def test_replay_without_a_truth_file_says_how_to_give_one(
        capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["run", "--emulate", "replay", "--quiet"]) == 2
    assert "--replay-truth FILE.csv" in capsys.readouterr().err


def test_before_its_first_time_a_record_moves_on_at_its_first_velocity() -> None:
    motion = RecordedMotion([1.0, 2.0], [[1, 0, 0, 0], [1, 0, 0, 0]],
                            [[0, 0, -10], [2, 0, -10]], [[2, 0, 0], [2, 0, 0]])
    k = motion.kinematics(0.25)
    assert k.position_ned_m == pytest.approx((-1.5, 0.0, -10.0))
    assert k.specific_force_body_m_s2 == pytest.approx((0.0, 0.0, -9.80665))
