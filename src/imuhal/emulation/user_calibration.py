"""The emulated board calibrated as its user would calibrate it (docs/calibration.md).

An emulated chip with sensor errors carries its datasheet offsets, scale errors and iron,
drawn once per device from the run seed. A real user of a profile without an accelerometer
or magnetometer record runs ``imuhal calibrate accel|mag`` first; here imuhal's own
procedures (accelerometer six positions, magnetometer ellipsoid) run on the emulated board
while it flies the ``calibration`` scenario with the same seed, so the records fit the errors
every later run with that seed has (what ``imuhal calibrate accel|mag --emulate calibration``
measures). Records the profile stores are kept; only the missing ones are measured.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from imuhal.calibration.accel import AccelSixPosition, AccelSixSettings
from imuhal.calibration.guidance import guided_order
from imuhal.calibration.mag import MagCalibrationProcedure, MagSettings
from imuhal.calibration.model import DeviceCalibration
from imuhal.calibration.procedure import Procedure
from imuhal.core.samples import Quantity, Sample
from imuhal.pipeline.pipeline import Pipeline
from imuhal.plugins.manager import Registry
from imuhal.profile.model import BoardProfile
from imuhal.profile.topology import chip_to_body_rotations, device_order

CALIBRATION_SCENARIO = "calibration"
"""The scenario the procedures fly: six held positions, then a figure of 8."""

USER_CALIBRATED = (Quantity.ACCEL, Quantity.MAG)
"""The channels a user calibrates once with a procedure (the gyro's offsets are measured at
every power-up by the bundled profiles, ``gyro_at_startup``)."""


def with_calibration(profile: BoardProfile, calibrations: Mapping[str, DeviceCalibration]
                     ) -> BoardProfile:
    """The profile with exactly ``calibrations`` stored in its devices (whatever its file
    holds is dropped)."""
    devices = {name: cfg.model_copy(update={"calibration": calibrations.get(name)})
               for name, cfg in profile.devices.items()}
    return profile.model_copy(update={"devices": devices})


def _learned_in_flight(cal: DeviceCalibration | None) -> set[Quantity]:
    """The channels ``cal`` asks to learn in flight."""
    if cal is None:
        return set()
    asked = {Quantity.MAG: cal.mag_in_flight, Quantity.ACCEL: cal.accel_in_flight}
    return {ch for ch, how in asked.items() if how is not None and how.enabled}


def missing_calibrations(profile: BoardProfile, registry: Registry
                         ) -> dict[str, tuple[Quantity, ...]]:
    """The accelerometer and magnetometer channels of each enabled device that the profile
    stores no record for, by device (profile order); devices missing none are left out. A
    magnetometer that learns its hard iron in flight (``mag_in_flight``) and an accelerometer
    that learns its offset in flight (``accel_in_flight``) are not missing."""
    out: dict[str, tuple[Quantity, ...]] = {}
    for name in device_order(profile):
        cfg = profile.devices[name]
        reg = registry.drivers.entries.get(cfg.driver)
        if not cfg.enabled or reg is None:
            continue
        cal = cfg.calibration
        learned = _learned_in_flight(cal)
        missing = tuple(ch for ch in USER_CALIBRATED if ch in reg.obj.channels
                        and (cal is None or getattr(cal, ch.value) is None)
                        and ch not in learned)
        if missing:
            out[name] = missing
    return out


def measure_calibrations(pipeline: Pipeline, profile: BoardProfile,
                         channels: Mapping[str, tuple[Quantity, ...]], duration_s: float,
                         ) -> dict[str, DeviceCalibration]:
    """Records for ``channels`` (device -> accel and/or mag), measured by imuhal's procedures
    (accelerometer six positions in the order a person handles the board, magnetometer
    ellipsoid) on the raw samples of ``pipeline`` (opened with ``calibrated=False`` over
    ``profile``'s board flying the calibration scenario) within ``duration_s``."""
    rotations = chip_to_body_rotations(profile)
    procedures: dict[tuple[str, Quantity], Procedure[Any]] = {}
    for device, chans in channels.items():
        if Quantity.ACCEL in chans:
            procedures[device, Quantity.ACCEL] = AccelSixPosition(
                AccelSixSettings(positions=guided_order(rotations[device])), device=device)
        if Quantity.MAG in chans:
            procedures[device, Quantity.MAG] = MagCalibrationProcedure(MagSettings(),
                                                                      device=device)
    if not procedures:
        return {}
    for event in pipeline.events(duration_s):
        if isinstance(event, Sample):
            done = [p.feed(event) for p in procedures.values()]
            if all(done):
                break
    records: dict[str, dict[str, Any]] = {}
    for (device, channel), procedure in procedures.items():
        records.setdefault(device, {})[channel.value] = procedure.finish().record()
    return {device: DeviceCalibration(**recs) for device, recs in records.items()}


def with_measured(profile: BoardProfile, measured: Mapping[str, DeviceCalibration]
                  ) -> BoardProfile:
    """``profile`` with the ``measured`` records added to what each device stores (a
    measured channel replaces the stored one; the rest, gyro offsets included, is kept)."""
    devices = dict(profile.devices)
    for device, cal in measured.items():
        stored = devices[device].calibration
        merged = cal if stored is None else stored.model_copy(
            update={ch: rec for ch, rec in cal.records().items()})
        devices[device] = devices[device].model_copy(update={"calibration": merged})
    return profile.model_copy(update={"devices": devices})
