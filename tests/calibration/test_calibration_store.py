"""Writing calibration into a profile: only the device's calibration block changes (comments
and order kept), what is written reads back equal, the replaced record and the old file are
kept, and an interrupted write leaves the old profile intact."""

from __future__ import annotations

import os
from datetime import UTC, datetime
from pathlib import Path

import pytest

from imuhal.calibrate import store
from imuhal.calibrate.store import replace_device_calibration, write_device_calibration
from imuhal.calibration.model import (
    CalibrationBinding,
    DeviceCalibration,
    GyroCalibration,
    MagCalibration,
)
from imuhal.core import atomic
from imuhal.profile.loader import parse_profile

PROFILE = """\
# board comment
schema_version: 1
name: store-test
buses:
  i2c1: {kind: i2c, device: /dev/i2c-1}   # trailing comment
devices:
  imu:
    driver: tc3
    bus: i2c1
    address: 0x19     # keep me
    calibration:
      accel: {offset_m_s2: [0.0, 0.0, 1.0]}
      # an old comment inside the block
  baro:
    driver: tc3
    bus: i2c1
    address: 0x18
    # last line of baro
estimators: {}
"""

GYRO = GyroCalibration(
    offset_rad_s=(0.0123456789012, -1.5e-05, 0.002), procedure="gyro-at-rest",
    date=datetime(2024, 5, 1, 12, 0, tzinfo=UTC), quality={"samples": 100.0},
    binding=CalibrationBinding(driver="tc3", bus="i2c1", address=0x19, identity="WHO_AM_I=0x5A"))


def _lines_outside(text: str, start: str, stop: str) -> list[str]:
    lines = text.splitlines()
    i = next(n for n, s in enumerate(lines) if s.strip().startswith(start))
    j = next(n for n, s in enumerate(lines) if n > i and s.strip().startswith(stop))
    return lines[:i] + lines[j:]


def test_only_the_calibration_block_changes_and_reads_back_equal() -> None:
    old = parse_profile(PROFILE, "p.yaml").devices["imu"].calibration
    assert old is not None
    cal = store.rounded(old.replaced("gyro", GYRO))
    text, warnings = replace_device_calibration(PROFILE, "p.yaml", "imu", cal)
    assert not warnings
    assert _lines_outside(text, "calibration:", "baro:") == \
        _lines_outside(PROFILE, "calibration:", "baro:")
    assert parse_profile(text, "p.yaml").devices["imu"].calibration == cal
    assert "    calibration:\n      accel:\n" in text  # block style at the device's indent


def test_a_device_without_calibration_gets_a_block_after_its_last_line() -> None:
    cal = DeviceCalibration(mag=MagCalibration(hard_iron_ut=(1.0, 2.0, 3.0)))
    text, _ = replace_device_calibration(PROFILE, "p.yaml", "baro", cal)
    assert "    # last line of baro\n    calibration:\n      mag:\n" in text
    assert text.endswith("estimators: {}\n")
    assert parse_profile(text, "p.yaml").devices["baro"].calibration == cal


def test_the_replaced_record_is_kept_as_previous() -> None:
    first = DeviceCalibration(gyro=GyroCalibration(offset_rad_s=(1.0, 0.0, 0.0)))
    second = first.replaced("gyro", GYRO)
    assert second.gyro == GYRO
    assert second.previous is not None and second.previous.gyro == first.gyro


def test_write_keeps_the_old_file_as_backup(tmp_path: Path) -> None:
    path = tmp_path / "board.yaml"
    path.write_text(PROFILE)
    bak, _ = write_device_calibration(path, "imu", DeviceCalibration(gyro=GYRO))
    assert bak == tmp_path / "board.yaml.bak" and bak.read_text() == PROFILE
    stored = parse_profile(path.read_text(), str(path)).devices["imu"].calibration
    assert stored is not None and stored.gyro is not None
    assert stored.gyro.offset_rad_s == pytest.approx(GYRO.offset_rad_s, rel=1e-8)
    assert stored.accel is None  # replaced as a whole: the caller decides what to keep


def test_a_crash_between_write_and_rename_leaves_the_old_profile_intact(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    path = tmp_path / "board.yaml"
    path.write_text(PROFILE)
    real_replace = os.replace

    def crash_on_profile(src: str | Path, dst: str | Path) -> None:
        if Path(dst) == path:
            raise KeyboardInterrupt("power cut")  # the new text is written and fsync'ed
        real_replace(src, dst)

    monkeypatch.setattr(atomic.os, "replace", crash_on_profile)
    with pytest.raises(KeyboardInterrupt):
        write_device_calibration(path, "imu", DeviceCalibration(gyro=GYRO))
    assert path.read_text() == PROFILE
    assert parse_profile(path.read_text(), str(path)).devices["imu"].calibration is not None
    assert [p.name for p in tmp_path.iterdir() if p.name.endswith(".tmp")] == []


def test_an_unknown_device_is_refused_and_nothing_is_written(tmp_path: Path) -> None:
    path = tmp_path / "board.yaml"
    path.write_text(PROFILE)
    with pytest.raises(store.CalibrationWriteError, match=r"no device 'gps'.*imu, baro"):
        write_device_calibration(path, "gps", DeviceCalibration(gyro=GYRO))
    assert path.read_text() == PROFILE and not (tmp_path / "board.yaml.bak").exists()


def test_floats_are_written_so_yaml_reads_them_as_numbers() -> None:
    assert store._float(1e-05) == "1.0e-05"
    assert float(store._float(0.1 + 0.2)) == pytest.approx(0.3, rel=1e-9)
