"""What the pipeline keeps per device and per estimator while it runs."""

from __future__ import annotations

from collections import Counter
from dataclasses import dataclass, field

from imuhal.calibration.model import DeviceCalibration
from imuhal.core.frames import FloatArray
from imuhal.drivers.base import Driver
from imuhal.estimation.base import Estimator


@dataclass
class DeviceRuntime:
    """One device: its driver, its rotation into the body frame, the calibration applied
    (start-up gyro offsets included), when it is next polled and what was counted."""

    name: str
    driver: Driver
    chip_to_body: FloatArray
    calibration: DeviceCalibration | None
    next_poll_ns: int = 0
    device_errors: int = 0
    warned: set[str] = field(default_factory=set)
    samples: int = 0
    flagged: Counter[str] = field(default_factory=Counter)


@dataclass
class EstimatorRuntime:
    """One estimator instance: which sources and sample types it takes, outputs counted."""

    name: str
    estimator: Estimator
    inputs: frozenset[str] | None
    consumes: tuple[type, ...]
    outputs: int = 0
