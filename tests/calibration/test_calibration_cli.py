"""``imuhal calibrate`` end to end on the emulated seed board (MAX21100 + HMC5883L behind its
I2C master, real drivers over register-level emulators): results are bound to the probed
chip, written into the profile with its comments, applied by the pipeline, shown by --show;
a refused procedure leaves the profile untouched."""

from __future__ import annotations

import math
import shutil
from pathlib import Path

import numpy as np
import pytest

from imuhal.cli.main import main
from imuhal.emulation import open_emulated
from imuhal.plugins.manager import Registry, load_registry
from imuhal.profile.loader import load_profile
from imuhal.sim.calibration import CalibrationScenario
from imuhal.sim.errors import SensorErrorModel, device_seed, error_spec_of

DATA = Path(__file__).resolve().parent.parent / "data" / "calibration"
DPS = math.pi / 180.0


@pytest.fixture(scope="module")
def chips() -> Registry:
    return load_registry()


@pytest.fixture
def board(tmp_path: Path) -> Path:
    path = tmp_path / "board.yaml"
    shutil.copy(DATA / "seed-board.yaml", path)
    return path


def test_gyro_calibration_is_measured_bound_and_written_keeping_comments(
        board: Path, chips: Registry, capsys: pytest.CaptureFixture[str]) -> None:
    before = board.read_text()
    assert main(["calibrate", "gyro", str(board), "--emulate", "calibration"]) == 0
    out = capsys.readouterr()
    assert "keep the board still" in out.err and "offset:" in out.out
    text = board.read_text()
    assert "# chip select 0" in text and "odr_hz: 75        # the seed's rate" in text
    assert Path(f"{board}.bak").read_text() == before
    gyro = load_profile(board, chips).devices["imu"].calibration.gyro  # type: ignore[union-attr]
    assert gyro is not None and gyro.binding is not None
    assert (gyro.binding.driver, gyro.binding.bus, gyro.binding.address) == ("max21100", "spi0", 0)
    assert gyro.binding.identity.startswith("WHO_AM_I")
    # the emulated chip's true offset: its datasheet error model, seeded per device, at the
    # board's temperature (the MAX21100 model has a thermal bias coefficient)
    spec = error_spec_of(chips.emulators.get("max21100"))
    model = SensorErrorModel(spec, seed=device_seed(7, "imu"))  # type: ignore[arg-type]
    temp = CalibrationScenario(seed=7).truth(0.0).temperature_degc
    truth = model.bias("gyro", temperature_degc=temp)
    assert np.abs(np.array(gyro.offset_rad_s) - np.array(truth)).max() / DPS < 0.05


def test_the_pipeline_applies_what_was_written_and_reports_a_foreign_binding(
        board: Path, chips: Registry) -> None:
    assert main(["calibrate", "gyro", str(board), "--emulate", "calibration"]) == 0
    with open_emulated(load_profile(board, chips), chips, scenario="static") as p:
        assert p.warnings == []
        assert p.devices["imu"].calibration.gyro is not None  # type: ignore[union-attr]
    board.write_text(board.read_text().replace("identity: WHO_AM_I", "identity: OTHER"))
    with open_emulated(load_profile(board, chips), chips, scenario="static") as p:
        assert any("imu: stored gyro calibration" in w and "NOT applied" in w
                   for w in p.warnings)


def test_mag_on_a_board_that_does_not_turn_is_refused_and_nothing_written(
        board: Path, capsys: pytest.CaptureFixture[str]) -> None:
    before = board.read_text()
    code = main(["calibrate", "mag", str(board), "--emulate", "static", "--timeout", "5"])
    err = capsys.readouterr().err
    assert code == 2
    assert "of field directions" in err and "figure of 8" in err
    assert board.read_text() == before and not Path(f"{board}.bak").exists()


def test_show_prints_the_stored_calibration(board: Path,
                                            capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["calibrate", "--show", str(board)]) == 0
    assert "no calibration stored" in capsys.readouterr().out
    assert main(["calibrate", "gyro", str(board), "--emulate", "calibration",
                 "--at-startup"]) == 0
    capsys.readouterr()
    assert main(["calibrate", "--show", str(board)]) == 0
    out = capsys.readouterr().out
    assert "imu (max21100 on spi0 at 0x00):" in out
    assert "gyro: gyro-at-rest" in out and "deg/s" in out
    assert "bound to: max21100 at spi0/0x00" in out
    assert "gyro offsets at start-up: on (100 samples)" in out


def test_a_device_without_the_channel_is_named_with_the_alternatives(
        board: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["calibrate", "mag", str(board), "--device", "imu"]) == 2
    assert "Devices with one: compass" in capsys.readouterr().err


@pytest.mark.parametrize("procedure", ["gyro", "accel"])
def test_an_ideal_emulated_calibration_succeeds(procedure: str, board: Path,
                                                tmp_path: Path) -> None:
    """Issue 26 item 8: ``--ideal`` (docs/calibration.md) always failed: noiseless chips
    repeat one raw frame, which their drivers flag FROZEN. The ideal chips keep their
    datasheet noise and lose every other error, so the result is the identity."""
    out = tmp_path / "calibrated.yaml"
    assert main(["calibrate", procedure, str(board), "--emulate", "calibration", "--ideal",
                 "--output", str(out)]) == 0
    written = load_profile(out, load_registry()).devices
    cal = next(d.calibration for d in written.values() if d.calibration is not None)
    if procedure == "gyro":
        assert np.allclose(cal.gyro.offset_rad_s, 0.0, atol=1e-3)
    else:
        assert np.allclose(cal.accel.offset_m_s2, 0.0, atol=0.02)
        assert np.allclose(cal.accel.scale, 1.0, atol=1e-3)


def test_noise_only_keeps_the_noise_and_drops_every_other_error() -> None:
    from imuhal.sim.errors import noise_only
    from imuhal_chips.mpu9250.emulator import MPU9250Emulator

    spec = error_spec_of(MPU9250Emulator)
    ideal = noise_only(spec)
    assert spec is not None and ideal is not None and spec.gyro is not None
    assert ideal.gyro is not None and ideal.gyro.noise_density == spec.gyro.noise_density
    assert ideal.gyro.bias == (0.0, 0.0, 0.0) and ideal.gyro.bias_std == 0.0
    assert ideal.gyro.scale_factor_std == 0.0 and ideal.gyro.cross_axis_std == 0.0
