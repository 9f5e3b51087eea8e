"""The accelerometer's in-flight learning fed from the fusion stream.

:class:`~imuhal.calibration.accel_in_flight.AccelOffsetLearner` needs samples of several
devices in time order (the IMU's gyro and accelerometer, the GNSS velocity, the
barometer) and, once, the attitude of an AHRS fed by the IMU. The pipeline's fusion queue
already holds exactly the valid, calibrated, body-frame frames the estimators take, in
fusion steps; :class:`AccelTeacher` reads every step after the estimators did, so a board
learns from what its estimators see (a device no estimator takes teaches nothing).
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Sequence

from imuhal.calibration.accel_in_flight import AccelOffsetLearner
from imuhal.core.blocks import Block
from imuhal.core.samples import (
    AccelSample,
    GyroSample,
    PressureSample,
    Sample,
    VelocitySample,
)
from imuhal.estimation.outputs import AttitudeEstimate, Estimate


class AccelTeacher:
    """One device's accelerometer learner and where its inputs come from.

    ``attitude_from``: the estimators (by instance name) fed by the device whose attitude
    may start the learner; ``apply``: called when the learner has a new offset to apply
    (the pipeline writes it into the device's calibration)."""

    def __init__(self, device: str, learner: AccelOffsetLearner,
                 attitude_from: frozenset[str], apply: Callable[[], None]) -> None:
        self.device = device
        self.learner = learner
        self.attitude_from = attitude_from
        self.apply = apply
        """Write the learner's applied offset into the device's calibration."""

    def feed(self, items: Iterable[Sample | Block], estimates: Sequence[Estimate]) -> None:
        """One fusion step: its frames in time order, then the estimates it produced."""
        samples: list[Sample] = []
        for item in items:
            if isinstance(item, Block):
                samples += item.samples()
            else:
                samples.append(item)
        samples.sort(key=lambda s: s.t_ns)
        for sample in samples:
            self._sample(sample)
        if self.learner.q is None:
            for e in estimates:
                if isinstance(e, AttitudeEstimate) and e.source in self.attitude_from:
                    self.learner.attitude(e.q_body_to_ned)

    def _sample(self, s: Sample) -> None:
        learner = self.learner
        changed = False
        if isinstance(s, GyroSample):
            if s.device == self.device:
                learner.gyro(s.t_ns, s.gyro_rad_s)
        elif isinstance(s, AccelSample):
            if s.device == self.device:
                learner.accel(s.t_ns, s.accel_m_s2)
        elif isinstance(s, VelocitySample):
            changed = learner.velocity(s.t_ns, s.velocity_ned_m_s, s.accuracy_m_s)
        elif isinstance(s, PressureSample):
            changed = learner.pressure(s.t_ns, s.pressure_pa)
        if changed:
            self.apply()
