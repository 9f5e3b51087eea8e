"""The uncalibrated seed-gps-vario learning its accelerometer offset and its hard iron in
flight: the board and what its shared ``thermal`` flight (tests/calibration/conftest.py)
shows."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from imuhal.calibration.model import (
    AccelInFlightSettings,
    DeviceCalibration,
    MagInFlightSettings,
)
from imuhal.plugins.manager import Registry
from imuhal.profile.bundled import default_profile_path
from imuhal.profile.loader import load_profile
from imuhal.profile.model import BoardProfile


@dataclass(frozen=True)
class ThermalLearningFlight:
    """What the uncalibrated seed-gps-vario, learning its accelerometer offset and its hard
    iron in flight, shows over 120 s of ``thermal`` (seed 1), and the six-position and
    ellipsoid calibration of the same board (seed 1) it is checked against."""

    mag_health_at_30_s: dict[str, Any]
    """The live view's health of device 'mag' after 30 s."""
    state_at_90_s: dict[str, Any]
    """The live view's whole state after 90 s, through JSON as the server sends it."""
    tilt_60_to_90_s_deg: list[float]
    """The AHRS's tilt error against the truth, each estimate from 60 s to 90 s."""
    imu_calibration_at_90_s: DeviceCalibration | None
    accel_status_at_90_s: dict[str, Any]
    summary_at_90_s: str
    mag_calibration_at_120_s: DeviceCalibration | None
    mag_status_at_120_s: dict[str, Any]
    reference: dict[str, DeviceCalibration]


def learning_gps_vario(registry: Registry) -> BoardProfile:
    """seed-gps-vario as stored (no accelerometer or magnetometer record), learning both in
    flight."""
    profile = load_profile(default_profile_path().parent / "seed-gps-vario.yaml", registry)
    devices = dict(profile.devices)
    imu_cal = devices["imu"].calibration
    assert imu_cal is not None
    devices["imu"] = devices["imu"].model_copy(update={"calibration": imu_cal.model_copy(
        update={"accel_in_flight": AccelInFlightSettings()})})
    devices["mag"] = devices["mag"].model_copy(
        update={"calibration": DeviceCalibration(mag_in_flight=MagInFlightSettings())})
    return profile.model_copy(update={"devices": devices})
