"""User calibration: models applied in the sensor frame before the mount rotation."""

from imuhal.calibration.model import (
    AccelCalibration,
    CalibrationBinding,
    DeviceCalibration,
    GyroCalibration,
    MagCalibration,
)

__all__ = [
    "AccelCalibration",
    "CalibrationBinding",
    "DeviceCalibration",
    "GyroCalibration",
    "MagCalibration",
]
