"""User calibration: models applied in the sensor frame before the mount rotation, the
procedures that measure them (pure, over raw sample streams), and storing them in profiles.

See docs/calibration.md. Procedures: :class:`GyroOffsetProcedure` (offsets at rest),
:class:`AccelSixPosition` (six positions, optional 3x3 misalignment),
:class:`MagCalibrationProcedure` (ellipsoid or min/max fit with coverage and residual checks).
"""

from imuhal.calibration.accel import AccelSixPosition, AccelSixResult, AccelSixSettings
from imuhal.calibration.errors import CalibrationError, CalibrationWriteError
from imuhal.calibration.gyro import GyroOffsetProcedure, GyroOffsetResult, GyroOffsetSettings
from imuhal.calibration.mag import MagCalibrationProcedure, MagResult, MagSettings
from imuhal.calibration.model import (
    AccelCalibration,
    CalibrationBinding,
    DeviceCalibration,
    GyroCalibration,
    GyroStartupSettings,
    MagCalibration,
    PreviousCalibration,
)
from imuhal.calibration.progress import Progress, ProgressKind

__all__ = [
    "AccelCalibration",
    "AccelSixPosition",
    "AccelSixResult",
    "AccelSixSettings",
    "CalibrationBinding",
    "CalibrationError",
    "CalibrationWriteError",
    "DeviceCalibration",
    "GyroCalibration",
    "GyroOffsetProcedure",
    "GyroOffsetResult",
    "GyroOffsetSettings",
    "GyroStartupSettings",
    "MagCalibration",
    "MagCalibrationProcedure",
    "MagResult",
    "MagSettings",
    "PreviousCalibration",
    "Progress",
    "ProgressKind",
]
