"""The magnetometer's hard iron learned in flight (issue 27, item 2): a sphere fit of the raw
readings taken while the board turns, with its uncertainty and a convergence criterion."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from tests.support.thermal_learning import ThermalLearningFlight

from imuhal.calibration.hard_iron import PROCEDURE, HardIronLearner
from imuhal.calibration.model import MagInFlightSettings
from imuhal.cli.main import main
from imuhal.plugins.manager import load_registry
from imuhal.profile.bundled import default_profile_path
from imuhal.profile.loader import load_profile, parse_profile

HARD_IRON_UT = np.array([12.0, -7.0, 20.0])
FIELD_NED_UT = np.array([20.0, 0.0, 40.0])  # 44.7 uT dipping 63 deg


def _turning(bank_deg: float, seconds: float = 120.0, rate_hz: float = 50.0) -> list[tuple]:
    """Raw readings of a board circling (20 s a turn), its bank swinging between 0 and
    ``bank_deg`` once a minute (into and out of the thermal), noise 0.3 uT."""
    rng = np.random.default_rng(1)
    out = []
    for i in range(int(seconds * rate_hz)):
        t = i / rate_hz
        yaw = 2 * math.pi * t / 20.0
        bank = math.radians(bank_deg) * (0.5 - 0.5 * math.cos(2 * math.pi * t / 60.0))
        cy, sy, cb, sb = math.cos(yaw), math.sin(yaw), math.cos(bank), math.sin(bank)
        yaw_m = np.array([[cy, sy, 0.0], [-sy, cy, 0.0], [0.0, 0.0, 1.0]])
        roll_m = np.array([[1.0, 0.0, 0.0], [0.0, cb, sb], [0.0, -sb, cb]])
        m = roll_m @ yaw_m @ FIELD_NED_UT + HARD_IRON_UT + rng.normal(0.0, 0.3, 3)
        out.append(tuple(float(v) for v in m))
    return out


def test_banked_turns_make_the_fit_converge_on_the_hard_iron() -> None:
    learner = HardIronLearner()
    for m in _turning(bank_deg=20.0):
        learner.feed(m)
    assert learner.converged
    h, std = learner.hard_iron_ut(), learner.std_ut()
    assert h is not None and std is not None
    assert np.allclose(h, HARD_IRON_UT, atol=1.5)
    assert max(std) <= MagInFlightSettings().max_std_ut
    assert learner.field_ut() == pytest.approx(float(np.linalg.norm(FIELD_NED_UT)), abs=1.5)


def test_a_board_at_rest_adds_one_reading_and_never_converges() -> None:
    rng = np.random.default_rng(2)
    learner = HardIronLearner()
    for _ in range(10_000):
        learner.feed(tuple(float(v) for v in FIELD_NED_UT + HARD_IRON_UT
                           + rng.normal(0.0, 0.3, 3)))
    assert learner.readings == 1 and not learner.converged


def test_a_steady_turn_gives_one_circle_of_readings_and_no_fit() -> None:
    # a circle lies on many spheres: the bank must change for the sphere to be found
    learner = HardIronLearner()
    for m in _steady_turn(bank_deg=20.0):
        learner.feed(m)
    std = learner.std_ut()
    assert not learner.converged and (std is None or max(std) > 0.5)


def _steady_turn(bank_deg: float) -> list[tuple]:
    bank = math.radians(bank_deg)
    out = []
    for i in range(6000):
        yaw = 2 * math.pi * i / 50.0 / 20.0
        cy, sy, cb, sb = math.cos(yaw), math.sin(yaw), math.cos(bank), math.sin(bank)
        yaw_m = np.array([[cy, sy, 0.0], [-sy, cy, 0.0], [0.0, 0.0, 1.0]])
        roll_m = np.array([[1.0, 0.0, 0.0], [0.0, cb, sb], [0.0, -sb, cb]])
        out.append(tuple(float(v) for v in roll_m @ yaw_m @ FIELD_NED_UT + HARD_IRON_UT))
    return out


def test_level_turns_leave_the_vertical_axis_unobservable_and_say_so() -> None:
    learner = HardIronLearner()
    for m in _turning(bank_deg=0.0):
        learner.feed(m)
    std = learner.std_ut()
    assert not learner.converged
    assert std is not None and std[2] > 10 * max(std[0], std[1])


def test_the_learned_record_is_a_magnetometer_record_with_its_uncertainty() -> None:
    learner = HardIronLearner()
    for m in _turning(bank_deg=20.0):
        learner.feed(m)
    record = learner.record()
    assert record.procedure == PROCEDURE
    assert record.soft_iron == ((1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0))
    assert {"readings", "std_x_ut", "std_y_ut", "std_z_ut", "field_ut"} <= set(record.quality)


def test_a_profile_asks_for_it_under_the_devices_calibration() -> None:
    text = (default_profile_path().parent / "seed-gps-vario.yaml").read_text(encoding="utf-8")
    text = text.replace('    mount: "+Y-X+Z"\n',
                        '    mount: "+Y-X+Z"\n    calibration:\n      mag_in_flight: {}\n')
    profile = parse_profile(text, "x.yaml", load_registry())
    cal = profile.devices["mag"].calibration
    assert cal is not None and cal.mag_in_flight == MagInFlightSettings()


def test_the_uncalibrated_gps_vario_learns_its_hard_iron_in_two_minutes_of_thermal(
        thermal_learning_flight: ThermalLearningFlight) -> None:
    flight = thermal_learning_flight
    applied, status = flight.mag_calibration_at_120_s, flight.mag_status_at_120_s
    # against the figure-of-8 ellipsoid calibration of the same board (seed 1)
    reference = flight.reference["mag"].mag
    assert reference is not None
    assert status["converged"]
    assert applied is not None and applied.mag is not None
    assert applied.mag.procedure == PROCEDURE
    assert np.allclose(applied.mag.hard_iron_ut, reference.hard_iron_ut, atol=1.0)


def _doc_line(start: str) -> str:
    """The line of docs/calibration.md that starts with ``start`` (indentation aside)."""
    page = Path(__file__).resolve().parents[2] / "docs" / "calibration.md"
    lines = [ln.strip() for ln in page.read_text(encoding="utf-8").splitlines()]
    return next(ln for ln in lines if ln.startswith(start))


def _learning_profile(tmp_path: Path) -> Path:
    text = (default_profile_path().parent / "seed-gps-vario.yaml").read_text(encoding="utf-8")
    path = tmp_path / "gps-vario.yaml"
    learning = '    mount: "+Y-X+Z"\n    calibration:\n      mag_in_flight: {}\n'
    path.write_text(text.replace('    mount: "+Y-X+Z"\n', learning), encoding="utf-8")
    return path


def test_imuhal_run_saves_the_learned_hard_iron_into_a_copy_of_the_profile(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    profile, saved = _learning_profile(tmp_path), tmp_path / "learned.yaml"
    assert main(["run", str(profile), "--emulate", "thermal", "--duration", "90", "--quiet",
                 "--skip-calibration", "--save-learned", str(saved)]) == 0
    printed = {line.strip() for line in capsys.readouterr().err.splitlines()}
    # docs/calibration.md quotes this run's summary line and its note, figures included
    assert _doc_line("mag: hard iron learned in flight, applied") in printed
    assert _doc_line("note: device 'imu' (mpu9250) has no accelerometer") in printed
    mag = load_profile(saved, load_registry()).devices["mag"].calibration
    assert mag is not None and mag.mag is not None and mag.mag.procedure == PROCEDURE
    assert "mag_in_flight" in profile.read_text(encoding="utf-8")  # the input is untouched
    assert "hard_iron_ut" not in profile.read_text(encoding="utf-8")


def test_imuhal_run_with_nothing_learned_writes_no_copy(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    profile, saved = _learning_profile(tmp_path), tmp_path / "learned.yaml"
    assert main(["run", str(profile), "--emulate", "static", "--duration", "2", "--quiet",
                 "--skip-calibration", "--save-learned", str(saved)]) == 0
    assert "nothing learned in flight to save" in capsys.readouterr().err
    assert not saved.exists()


def test_the_live_views_health_shows_the_hard_iron_and_its_uncertainty(
        thermal_learning_flight: ThermalLearningFlight) -> None:
    # the state after 90 s went through json.dumps(allow_nan=False), as the server sends it
    learning = thermal_learning_flight.mag_health_at_30_s["learned"]
    state = thermal_learning_flight.state_at_90_s
    learned = state["health"]["mag"]["learned"]
    assert not learning["converged"] and learning["readings"] > 0
    assert learned["converged"] and max(learned["std_ut"]) <= 0.5
    assert learned["criterion"] == {"min_readings": 100, "max_std_ut": 0.5}
    assert state["health"]["imu"]["learned"] is None
