"""Calibration a user actually has (issue 27, item 1): `imuhal run` names each missing
accelerometer and magnetometer record once with what it may cost, and an emulated board is
calibrated first as docs/calibration.md asks of its user (unless --skip-calibration)."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from imuhal.bus.recording.format import open_recording
from imuhal.calibrate.as_user import calibrate_emulated, missing_calibration_notes
from imuhal.calibration.model import DeviceCalibration
from imuhal.cli.main import main
from imuhal.core.samples import Quantity
from imuhal.emulation import calibrated_as_user, open_emulated
from imuhal.estimation.outputs import AttitudeEstimate
from imuhal.plugins.manager import Registry, load_registry
from imuhal.profile.bundled import default_profile_path
from imuhal.profile.loader import load_profile, parse_profile
from imuhal.profile.model import BoardProfile
from imuhal_filters.common.quat import tilt_error_deg

GPS_VARIO = default_profile_path().parent / "seed-gps-vario.yaml"


@pytest.fixture(scope="module")
def registry() -> Registry:
    return load_registry()


@pytest.fixture(scope="module")
def gps_vario(registry: Registry) -> BoardProfile:
    return load_profile(GPS_VARIO, registry)


def test_a_missing_accelerometer_record_is_named_with_the_tilt_the_chips_offset_may_cost(
        gps_vario: BoardProfile, registry: Registry) -> None:
    notes = missing_calibration_notes(gps_vario, registry)
    accel = [n for n in notes if "accelerometer" in n]
    assert len(accel) == 1
    # the MPU-9250's specified zero-g offset, +-60 mg: atan(0.060) = 3.43 deg
    assert "'imu' (mpu9250)" in accel[0] and "60 mg" in accel[0]
    assert f"{math.degrees(math.atan(0.060)):.1f} deg" in accel[0]
    assert "imuhal calibrate accel" in accel[0]


def test_a_missing_magnetometer_record_is_named_with_the_heading_it_turns(
        gps_vario: BoardProfile, registry: Registry) -> None:
    mag = [n for n in missing_calibration_notes(gps_vario, registry) if "magnetometer" in n]
    assert len(mag) == 1 and "'mag' (ak8963)" in mag[0] and "heading" in mag[0]


def test_the_board_calibrated_as_its_user_keeps_the_stored_gyro_setting_and_adds_the_rest(
        gps_vario: BoardProfile, registry: Registry,
        gps_vario_calibration: dict[str, DeviceCalibration]) -> None:
    calibrated, measured = calibrated_as_user(gps_vario, registry, seed=1)
    assert measured == {"imu": (Quantity.ACCEL,), "mag": (Quantity.MAG,)}
    imu = calibrated.devices["imu"].calibration
    assert imu is not None and imu.accel is not None
    assert imu.gyro_at_startup == gps_vario.devices["imu"].calibration.gyro_at_startup  # type: ignore[union-attr]
    # the same records as the flight studies' calibrated board (one procedure, one board)
    # measure_board_calibration(gps_vario, registry, seed=1), shared (conftest.py)
    studied = gps_vario_calibration
    assert imu.accel == studied["imu"].accel
    assert calibrated.devices["mag"].calibration == studied["mag"]
    assert missing_calibration_notes(calibrated, registry) == []
    assert calibrated_as_user(calibrated, registry, seed=1) == (calibrated, {})


def _mean_tilt_at_rest_deg(profile: BoardProfile, registry: Registry, **kw: bool) -> float:
    errors = []
    with open_emulated(profile, registry, scenario="static", seed=1, **kw) as pipeline:
        world = pipeline.board.scenario  # type: ignore[union-attr]
        for e in pipeline.events(4.0):
            if isinstance(e, AttitudeEstimate) and e.source == "ahrs" and e.t_ns >= 1e9:
                truth = tuple(float(v) for v in world.truth(e.t_ns / 1e9).q_body_to_ned)
                errors.append(tilt_error_deg(e.q_body_to_ned, truth))
    return float(np.mean(errors))


def test_open_emulated_calibrating_the_missing_records_levels_the_board_at_rest(
        gps_vario: BoardProfile, registry: Registry) -> None:
    # seed 1's MPU-9250 draws 48.5 mg of horizontal offset: 2.8 deg of tilt, uncalibrated
    assert _mean_tilt_at_rest_deg(gps_vario, registry) > 2.0
    assert _mean_tilt_at_rest_deg(gps_vario, registry, calibrate_missing=True) < 0.5


def test_the_measured_records_are_written_into_the_profile_text_as_calibrate_writes_them(
        gps_vario: BoardProfile, registry: Registry) -> None:
    text = GPS_VARIO.read_text(encoding="utf-8")
    run = calibrate_emulated(gps_vario, text, str(GPS_VARIO), registry, seed=1)
    assert run.measured == {"imu": ("accel",), "mag": ("mag",)}
    assert "# The seed author's later GPS vario" in run.text  # comments kept
    assert parse_profile(run.text, "x.yaml", registry) == run.profile
    assert run.profile.devices["imu"].calibration.accel is not None  # type: ignore[union-attr]


def test_imuhal_run_emulated_says_it_calibrated_first_and_records_the_calibrated_profile(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    record = tmp_path / "run.imrec"
    assert main(["run", str(GPS_VARIO), "--emulate", "static", "--duration", "0.5",
                 "--quiet", "--record", str(record)]) == 0
    err = capsys.readouterr().err
    assert err.count("calibrated first") == 1
    assert "the accelerometer of 'imu' (six positions)" in err and "note:" not in err
    header = open_recording(record).header
    assert "offset_m_s2" in header["profile_yaml"]


def test_imuhal_run_skip_calibration_flies_the_stored_profile_and_names_each_gap_once(
        capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["run", str(GPS_VARIO), "--emulate", "static", "--duration", "0.5",
                 "--quiet", "--skip-calibration"]) == 0
    err = capsys.readouterr().err
    assert "calibrated first" not in err
    assert err.count("note: device 'imu' (mpu9250) has no accelerometer calibration") == 1
    assert err.count("note: device 'mag' (ak8963) has no magnetometer calibration") == 1


def test_skip_calibration_on_real_hardware_is_a_one_line_error(
        capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["run", str(GPS_VARIO), "--skip-calibration"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--skip-calibration is for emulated runs" in err[0]
