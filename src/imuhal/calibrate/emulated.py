"""An emulated board calibrated as its user would calibrate it, for studies of calibrated
flight (the flight benchmark, the flight-target tests).

An emulated chip with sensor errors carries its datasheet bias, scale and iron errors,
drawn once per device from the run seed; the board a flight study needs is that board
after calibration. :func:`measure_board_calibration` runs imuhal's own procedures on it
(accelerometer six positions, magnetometer ellipsoid: what ``imuhal calibrate accel|mag
--emulate calibration`` does) while it flies the ``calibration`` scenario with the same
seed, so the records fit the errors every later run with that seed has.
"""

from __future__ import annotations

from collections.abc import Mapping

from imuhal.calibrate.session import guided_order, open_raw_pipeline, pick_device
from imuhal.calibration.accel import AccelSixPosition, AccelSixSettings
from imuhal.calibration.mag import MagCalibrationProcedure, MagSettings
from imuhal.calibration.model import DeviceCalibration, GyroStartupSettings
from imuhal.core.samples import Channel, Sample
from imuhal.plugins.manager import Registry
from imuhal.profile.model import BoardProfile
from imuhal.profile.topology import chip_to_body_rotations


def with_calibration(profile: BoardProfile, calibrations: Mapping[str, DeviceCalibration],
                     *, gyro_startup: str | None = None) -> BoardProfile:
    """The profile with exactly ``calibrations`` stored in its devices (whatever its file
    holds is dropped); device ``gyro_startup`` re-measures its gyro offsets at every
    power-up (``gyro_at_startup``)."""
    devices = {}
    for name, cfg in profile.devices.items():
        cal = calibrations.get(name)
        if name == gyro_startup:
            cal = (cal or DeviceCalibration()).model_copy(
                update={"gyro_at_startup": GyroStartupSettings()})
        devices[name] = cfg.model_copy(update={"calibration": cal})
    return profile.model_copy(update={"devices": devices})


def measure_board_calibration(profile: BoardProfile, registry: Registry, *, seed: int
                              ) -> dict[str, DeviceCalibration]:
    """The accelerometer (six positions) and magnetometer (ellipsoid) records of the emulated
    board with ``seed``'s sensor errors, measured by imuhal's procedures on the board flying
    the ``calibration`` scenario. The board must have one device of each."""
    accel_dev = pick_device(profile, registry, Channel.ACCEL)
    mag_dev = pick_device(profile, registry, Channel.MAG)
    chip_to_body = chip_to_body_rotations(profile)[accel_dev]
    accel = AccelSixPosition(AccelSixSettings(positions=guided_order(chip_to_body)),
                             device=accel_dev)
    mag = MagCalibrationProcedure(MagSettings(), device=mag_dev)
    duration_s = registry.scenarios.get("calibration").default_duration_s
    raw = with_calibration(profile, {})
    with open_raw_pipeline(raw, registry, emulate="calibration", seed=seed) as pipeline:
        for event in pipeline.events(duration_s):
            if isinstance(event, Sample):
                accel.feed(event)
                mag.feed(event)
                if accel.done and mag.done:
                    break
    return {accel_dev: DeviceCalibration(accel=accel.finish().record()),
            mag_dev: DeviceCalibration(mag=mag.finish().record())}


def calibrated_board(profile: BoardProfile, registry: Registry, *, seed: int) -> BoardProfile:
    """``profile`` with the accelerometer and magnetometer records measured on its emulated
    board (``seed``) and the gyro offsets measured at every power-up, as the seed asks."""
    return with_calibration(profile, measure_board_calibration(profile, registry, seed=seed),
                            gyro_startup=pick_device(profile, registry, Channel.GYRO))
