"""Stored calibration and how it is applied.

Inertial (accel, gyro): corrected = M @ diag(s) @ (raw - b), with b in the channel's SI unit.
Magnetic: corrected = S @ (raw - h), h in uT. Both act in the chip's sensor frame, before the
mount rotation (docs/units-and-frames.md). Each record is bound to the device it was measured
on; the pipeline refuses to apply a record whose binding does not match the probed chip.
"""

from __future__ import annotations

from datetime import datetime
from typing import Annotated

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, field_validator

Vec3 = tuple[float, float, float]
Mat3 = tuple[Vec3, Vec3, Vec3]
IDENTITY3: Mat3 = ((1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0))


class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


class CalibrationBinding(_Strict):
    """The device a calibration was measured on."""

    driver: str
    bus: str
    address: int
    identity: str
    calibration_version: int = 1


class _Record(_Strict):
    binding: CalibrationBinding | None = None
    procedure: str = "manual"
    date: datetime | None = None
    quality: dict[str, float] = Field(default_factory=dict)


def _check_matrix(m: Mat3) -> Mat3:
    a = np.asarray(m, dtype=float)
    if not np.all(np.isfinite(a)):
        raise ValueError("matrix entries must be finite")
    if abs(float(np.linalg.det(a))) < 1e-6:
        raise ValueError("matrix is singular: it would collapse an axis")
    return m


class AccelCalibration(_Record):
    offset_m_s2: Vec3 = (0.0, 0.0, 0.0)
    scale: Annotated[Vec3, Field(description="multiplier per axis (1/sensitivity error)")] = (
        1.0, 1.0, 1.0)
    misalignment: Mat3 = IDENTITY3

    _m = field_validator("misalignment")(_check_matrix)

    def apply(self, raw: Vec3) -> Vec3:
        return _inertial(raw, self.offset_m_s2, self.scale, self.misalignment)


class GyroCalibration(_Record):
    offset_rad_s: Vec3 = (0.0, 0.0, 0.0)
    scale: Vec3 = (1.0, 1.0, 1.0)
    misalignment: Mat3 = IDENTITY3

    _m = field_validator("misalignment")(_check_matrix)

    def apply(self, raw: Vec3) -> Vec3:
        return _inertial(raw, self.offset_rad_s, self.scale, self.misalignment)


class MagCalibration(_Record):
    hard_iron_ut: Vec3 = (0.0, 0.0, 0.0)
    soft_iron: Mat3 = IDENTITY3

    _m = field_validator("soft_iron")(_check_matrix)

    def apply(self, raw: Vec3) -> Vec3:
        v = np.asarray(self.soft_iron) @ (np.asarray(raw) - np.asarray(self.hard_iron_ut))
        return (float(v[0]), float(v[1]), float(v[2]))


class DeviceCalibration(_Strict):
    accel: AccelCalibration | None = None
    gyro: GyroCalibration | None = None
    mag: MagCalibration | None = None


def _inertial(raw: Vec3, offset: Vec3, scale: Vec3, m: Mat3) -> Vec3:
    v = np.asarray(m) @ (np.asarray(scale) * (np.asarray(raw) - np.asarray(offset)))
    return (float(v[0]), float(v[1]), float(v[2]))
