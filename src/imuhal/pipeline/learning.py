"""The accelerometer's in-flight learning fed from the fusion stream.

:class:`~imuhal.calibration.accel_in_flight.AccelOffsetLearner` needs samples of several
devices in time order (the IMU's gyro and accelerometer, the GNSS velocity, the
barometer) and, once, the attitude of an AHRS fed by the IMU. The pipeline's fusion queue
already holds exactly the valid, calibrated, body-frame frames the estimators take, in
fusion steps; :class:`AccelTeacher` reads every step after the estimators did, so a board
learns from what its estimators see (a device no estimator takes teaches nothing).

**What learns by default** (:func:`learned_by_default`): a device whose profile stores no
accelerometer (magnetometer) record and does not set ``accel_in_flight``
(``mag_in_flight``) learns it in flight with the learner's default settings wherever it is
observable: the magnetometer's hard iron always (turns rotate the field), the
accelerometer's offset when some enabled device of the board gives a GNSS velocity (without
one only the vertical axis would be, from the barometer). A run that measures the records
before it flies (an emulated ``imuhal run``, ``open_emulated(calibrate_missing=True)``)
stores them first, so nothing of it learns; ``accel_in_flight: off`` / ``mag_in_flight:
off`` in the profile turns the default off.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Sequence

from imuhal.calibration.accel_in_flight import AccelOffsetLearner
from imuhal.calibration.model import AccelInFlightSettings, MagInFlightSettings
from imuhal.core.blocks import Block
from imuhal.core.samples import (
    AccelSample,
    GyroSample,
    PressureSample,
    Quantity,
    Sample,
    VelocitySample,
)
from imuhal.estimation.outputs import AttitudeEstimate, Estimate
from imuhal.plugins.manager import Registry
from imuhal.profile.model import BoardProfile

LEARNED_IN_FLIGHT = (Quantity.ACCEL, Quantity.MAG)
"""The channels a learner exists for, in the order they are named."""

InFlightSettings = AccelInFlightSettings | MagInFlightSettings


def in_flight_setting(profile: BoardProfile, device: str, channel: Quantity
                      ) -> InFlightSettings | None:
    """What ``device``'s profile says about learning ``channel`` in flight (None: nothing,
    the default decides)."""
    cal = profile.devices[device].calibration
    return None if cal is None else getattr(cal, f"{channel.value}_in_flight")


def learned_by_default(profile: BoardProfile, registry: Registry
                       ) -> dict[str, tuple[Quantity, ...]]:
    """The channels each enabled device learns in flight by default, by device (profile
    order; devices learning none left out): those its driver measures, with no record
    stored and no ``<channel>_in_flight`` setting, and observable on this board (see the
    module's docstring)."""
    drivers = {name: registry.drivers.entries.get(cfg.driver)
               for name, cfg in profile.devices.items() if cfg.enabled}
    has_velocity = any(reg is not None and Quantity.VELOCITY in reg.obj.channels
                       for reg in drivers.values())
    out: dict[str, tuple[Quantity, ...]] = {}
    for name, reg in drivers.items():
        cal = profile.devices[name].calibration
        learned = tuple(
            ch for ch in LEARNED_IN_FLIGHT
            if reg is not None and ch in reg.obj.channels
            and (ch is Quantity.MAG or has_velocity)
            and (cal is None or cal.record_for(ch.value) is None)
            and in_flight_setting(profile, name, ch) is None)
        if learned:
            out[name] = learned
    return out


def learning_settings(profile: BoardProfile, device: str, channel: Quantity,
                      by_default: dict[str, tuple[Quantity, ...]]) -> InFlightSettings | None:
    """The settings ``device`` learns ``channel`` in flight with (None: it does not): the
    profile's when it sets them (``off``: None), else the learner's defaults when
    ``by_default`` (:func:`learned_by_default`) names it."""
    asked = in_flight_setting(profile, device, channel)
    if asked is not None:
        return asked if asked.enabled else None
    if channel not in by_default.get(device, ()):
        return None
    return AccelInFlightSettings() if channel is Quantity.ACCEL else MagInFlightSettings()


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
        if s.flags:
            # a gyro word clipped at its rail reaches the AHRS flagged (angular-rate
            # recovery); its true rate is unknown, so the learner's own attitude never
            # integrates it: a rate that short a gap is carried by the next valid sample
            return
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
