"""Learning in flight by default (issue 27, item 2): a device with no accelerometer
(magnetometer) record learns it in flight when nothing measures it before the flight and it
is observable on the board; a stored record, a calibration run first, or ``off`` in the
profile means no learning; a bad value is a one-line profile error."""

from __future__ import annotations

from pathlib import Path

import pytest

from imuhal.cli.main import main
from imuhal.emulation import open_emulated
from imuhal.pipeline.pipeline import Pipeline
from imuhal.plugins.manager import Registry, load_registry
from imuhal.profile.bundled import default_profile_path
from imuhal.profile.loader import load_profile, parse_profile
from imuhal.profile.model import BoardProfile

PROFILES = default_profile_path().parent
GPS_VARIO = PROFILES / "seed-gps-vario.yaml"


@pytest.fixture(scope="module")
def registry() -> Registry:
    return load_registry()


def _learning(pipeline: Pipeline) -> dict[str, set[str]]:
    """What each device of an opened pipeline learns in flight."""
    out: dict[str, set[str]] = {}
    for name, dev in pipeline.devices.items():
        if dev.mag_learner is not None:
            out.setdefault(name, set()).add("mag")
        if dev.accel_teacher is not None:
            out.setdefault(name, set()).add("accel")
    return out


def _gps_vario(registry: Registry, imu: str = "", mag: str = "") -> BoardProfile:
    """The bundled seed-gps-vario with ``imu`` added under the IMU's calibration and ``mag``
    as the magnetometer's calibration (YAML flow mappings' contents)."""
    text = GPS_VARIO.read_text(encoding="utf-8")
    text = text.replace("      gyro_at_startup: {enabled: true, samples: 100}\n",
                        "      gyro_at_startup: {enabled: true, samples: 100}\n" + imu)
    text = text.replace("    mount: \"+Y-X+Z\"\n", f"    mount: \"+Y-X+Z\"\n{mag}")
    return parse_profile(text, str(GPS_VARIO), registry)


def test_a_board_without_records_learns_both_in_flight_when_nothing_calibrates_it_first(
        registry: Registry) -> None:
    with open_emulated(load_profile(GPS_VARIO, registry), registry) as pipeline:
        assert _learning(pipeline) == {"imu": {"accel"}, "mag": {"mag"}}


def test_without_a_gnss_velocity_only_the_hard_iron_is_learned_by_default(
        registry: Registry) -> None:
    profile = load_profile(PROFILES / "seed-paraglider-vario.yaml", registry)
    with open_emulated(profile, registry) as pipeline:
        assert _learning(pipeline) == {"mag": {"mag"}}


def test_a_stored_record_is_not_learned_again_while_the_missing_one_is(
        registry: Registry) -> None:
    profile = _gps_vario(registry, imu="      accel: {offset_m_s2: [0.1, -0.2, 0.05]}\n")
    with open_emulated(profile, registry) as pipeline:
        assert _learning(pipeline) == {"mag": {"mag"}}


def test_stored_records_of_both_mean_no_learning(registry: Registry) -> None:
    profile = _gps_vario(
        registry, imu="      accel: {offset_m_s2: [0.1, -0.2, 0.05]}\n",
        mag="    calibration:\n      mag: {hard_iron_ut: [10.0, 9.0, 30.0]}\n")
    with open_emulated(profile, registry) as pipeline:
        assert _learning(pipeline) == {}


def test_a_board_calibrated_before_the_flight_does_not_learn_in_flight(
        registry: Registry) -> None:
    with open_emulated(load_profile(GPS_VARIO, registry), registry,
                       calibrate_missing=True) as pipeline:
        assert _learning(pipeline) == {}


@pytest.mark.parametrize("off", ["off", "false", "{enabled: false}"])
def test_off_in_the_profile_wins_over_the_default(registry: Registry, off: str) -> None:
    profile = _gps_vario(registry, imu=f"      accel_in_flight: {off}\n",
                         mag=f"    calibration:\n      mag_in_flight: {off}\n")
    with open_emulated(profile, registry) as pipeline:
        assert _learning(pipeline) == {}


def test_imuhal_run_says_which_device_learns_what_by_default_and_how_to_turn_it_off(
        capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["run", str(GPS_VARIO), "--emulate", "thermal", "--duration", "0.5",
                 "--skip-calibration", "--quiet"]) == 0
    notes = [line for line in capsys.readouterr().err.splitlines() if "by default" in line]
    assert len(notes) == 2
    imu, mag = notes
    assert "'imu'" in imu and "accelerometer's offset" in imu \
        and "`accel_in_flight: off` under devices.imu.calibration" in imu
    assert "'mag'" in mag and "hard iron" in mag and "`mag_in_flight: off`" in mag


def test_imuhal_run_says_nothing_of_learning_when_it_calibrates_first(
        capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["run", str(GPS_VARIO), "--emulate", "thermal", "--duration", "0.5",
                 "--quiet"]) == 0
    assert "by default" not in capsys.readouterr().err


def test_a_bad_learning_value_is_a_one_line_profile_error_naming_the_fix(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    text = GPS_VARIO.read_text(encoding="utf-8").replace(
        "      gyro_at_startup: {enabled: true, samples: 100}\n",
        "      gyro_at_startup: {enabled: true, samples: 100}\n      accel_in_flight: maybe\n")
    path = tmp_path / "board.yaml"
    path.write_text(text, encoding="utf-8")
    assert main(["run", str(path), "--emulate", "thermal", "--duration", "0.5"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1
    assert "devices.imu.calibration.accel_in_flight" in err[0]
    assert "`accel_in_flight: off`" in err[0] and "'maybe'" in err[0]
