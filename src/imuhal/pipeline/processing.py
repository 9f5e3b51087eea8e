"""The per-sample steps between a driver and the estimators, as plain functions.

Order (fixed, docs/units-and-frames.md): validity check -> calibration (sensor frame) ->
rotation chip -> body. A flagged sample goes through unchanged apart from the rotation, so
sinks can still log it; it is never handed to an estimator.
"""

from __future__ import annotations

import math
from typing import Protocol

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
    Vec3,
    VectorSample,
)


class _Correction(Protocol):
    """A calibration record: corrects a sensor-frame vector."""

    def apply(self, raw: Vec3) -> Vec3: ...


def values_of(sample: Sample) -> tuple[float, ...]:
    """The sample's numbers (a vector's three components, or the scalar)."""
    if isinstance(sample, VectorSample):
        return sample.vector
    if isinstance(sample, ScalarSample):
        return (sample.scalar,)
    return ()


def validity_flags(sample: Sample, full_scale: float | None, last_t_ns: int | None
                   ) -> SampleFlag:
    """The pipeline's part of validity, on top of what the driver flagged: every value
    finite (else NAN), none beyond ``full_scale`` (the chip's configured full scale, SI;
    None: not declared; else OUT_OF_RANGE), and not older than ``last_t_ns``, the last valid
    sample of the same device and quantity (else OUT_OF_ORDER). This is the only NaN check."""
    flags = sample.flags
    values = values_of(sample)
    if not all(map(math.isfinite, values)):
        flags |= SampleFlag.NAN
    elif full_scale is not None and values and max(map(abs, values)) > full_scale:
        flags |= SampleFlag.OUT_OF_RANGE
    if last_t_ns is not None and sample.t_ns < last_t_ns:
        flags |= SampleFlag.OUT_OF_ORDER
    return flags


def _record(sample: VectorSample, calibration: DeviceCalibration | None) -> _Correction | None:
    """The calibration record of the sample's quantity, if any."""
    if calibration is None:
        return None
    if isinstance(sample, AccelSample):
        return calibration.accel
    if isinstance(sample, GyroSample):
        return calibration.gyro
    if isinstance(sample, MagSample):
        return calibration.mag
    return calibration.record_for(sample.channel.name)  # a plugin's vector quantity


def _rotate(m: FloatArray | list[list[float]], v: Vec3) -> Vec3:
    """``m @ v`` in plain floats: cheaper than a numpy product for one vector (every sample
    comes through here). The same floats as numpy's own loop, signed zeros included; BLAS,
    which numpy may use instead, can differ in the last bit for a matrix that is not a
    signed permutation. ``m`` may be given as nested lists of floats already."""
    rows = m if type(m) is list else np.asarray(m, dtype=float).tolist()
    (a, b, c), (d, e, f), (g, h, i) = rows
    x, y, z = v
    # Each sum starts from +0.0 as numpy's does, so an exact zero keeps numpy's sign (+0.0).
    return (0.0 + a * x + b * y + c * z, 0.0 + d * x + e * y + f * z,
            0.0 + g * x + h * y + i * z)


def calibrate_to_body(sample: Sample, calibration: DeviceCalibration | None,
                      chip_to_body: FloatArray | list[list[float]]) -> Sample:
    """Apply the stored calibration of the sample's channel (sensor frame), then rotate the
    vector into the NED body frame; the sample is copied once (copying a frozen sample costs
    more than the arithmetic). Scalar samples pass unchanged."""
    if not isinstance(sample, VectorSample):
        return sample
    record = _record(sample, calibration)
    vector = sample.vector if record is None else record.apply(sample.vector)
    if sample.frame is Frame.BODY_NED:
        return sample if record is None else sample.with_vector(vector, sample.frame)
    return sample.with_vector(_rotate(chip_to_body, vector), Frame.BODY_NED)
