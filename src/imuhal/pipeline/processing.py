"""The per-sample steps between a driver and the estimators, as plain functions.

Order (fixed, docs/units-and-frames.md): quality check -> calibration (sensor frame) ->
rotation chip -> body. A flagged sample goes through unchanged apart from the rotation, so
sinks can still log it; it is never handed to an estimator.
"""

from __future__ import annotations

import math

import numpy as np

from imuhal.calibration.model import DeviceCalibration
from imuhal.core.frames import FloatArray
from imuhal.core.samples import (
    AccelSample,
    Frame,
    GyroSample,
    MagSample,
    Sample,
    SampleFlag,
    ScalarSample,
    VectorSample,
)


def quality_flags(sample: Sample) -> SampleFlag:
    """NaN/inf check on top of whatever the driver flagged."""
    if isinstance(sample, VectorSample):
        values = sample.vector
    elif isinstance(sample, ScalarSample):
        values = (sample.scalar,)
    else:
        return sample.flags
    if not all(map(math.isfinite, values)):
        return sample.flags | SampleFlag.NAN
    return sample.flags


def calibrate(sample: Sample, calibration: DeviceCalibration | None) -> Sample:
    """Apply the stored calibration of the sample's channel, in the sensor frame."""
    if calibration is None or not isinstance(sample, VectorSample):
        return sample
    record = None
    if isinstance(sample, AccelSample):
        record = calibration.accel
    elif isinstance(sample, GyroSample):
        record = calibration.gyro
    elif isinstance(sample, MagSample):
        record = calibration.mag
    if record is None:
        return sample
    return sample.with_vector(record.apply(sample.vector), sample.frame)


def to_body(sample: Sample, chip_to_body: FloatArray) -> Sample:
    """Rotate a sensor-frame vector sample into the NED body frame."""
    if not isinstance(sample, VectorSample) or sample.frame is Frame.BODY_NED:
        return sample
    # Plain floats: cheaper than a numpy product for one vector (every sample comes through
    # here), and the same floats as ``chip_to_body @ v``.
    (a, b, c), (d, e, f), (g, h, i) = np.asarray(chip_to_body, dtype=float).tolist()
    x, y, z = sample.vector
    return sample.with_vector((a * x + b * y + c * z, d * x + e * y + f * z,
                               g * x + h * y + i * z), Frame.BODY_NED)
