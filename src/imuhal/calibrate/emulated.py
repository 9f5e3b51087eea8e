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

from imuhal.calibrate.session import open_raw_pipeline, pick_device
from imuhal.calibration.model import DeviceCalibration, GyroStartupSettings
from imuhal.core.samples import Quantity
from imuhal.emulation import user_calibration
from imuhal.plugins.manager import Registry
from imuhal.profile.model import BoardProfile


def with_calibration(profile: BoardProfile, calibrations: Mapping[str, DeviceCalibration],
                     *, gyro_startup: str | None = None) -> BoardProfile:
    """The profile with exactly ``calibrations`` stored in its devices (whatever its file
    holds is dropped); device ``gyro_startup`` re-measures its gyro offsets at every
    power-up (``gyro_at_startup``)."""
    if gyro_startup is not None:
        cal = calibrations.get(gyro_startup) or DeviceCalibration()
        calibrations = {**calibrations, gyro_startup: cal.model_copy(
            update={"gyro_at_startup": GyroStartupSettings()})}
    return user_calibration.with_calibration(profile, calibrations)


def measure_board_calibration(profile: BoardProfile, registry: Registry, *, seed: int
                              ) -> dict[str, DeviceCalibration]:
    """The accelerometer (six positions) and magnetometer (ellipsoid) records of the emulated
    board with ``seed``'s sensor errors, measured by imuhal's procedures on the board flying
    the ``calibration`` scenario (imuhal.emulation.user_calibration). The board must have
    one device of each."""
    accel_dev = pick_device(profile, registry, Quantity.ACCEL)
    mag_dev = pick_device(profile, registry, Quantity.MAG)
    channels = {accel_dev: (Quantity.ACCEL,)}
    channels[mag_dev] = (*channels.get(mag_dev, ()), Quantity.MAG)
    raw = with_calibration(profile, {})
    duration_s = registry.scenarios.get(user_calibration.CALIBRATION_SCENARIO).default_duration_s
    with open_raw_pipeline(raw, registry, emulate=user_calibration.CALIBRATION_SCENARIO,
                           seed=seed) as pipeline:
        return user_calibration.measure_calibrations(pipeline, raw, channels, duration_s)


def calibrated_board(profile: BoardProfile, registry: Registry, *, seed: int) -> BoardProfile:
    """``profile`` with the accelerometer and magnetometer records measured on its emulated
    board (``seed``) and the gyro offsets measured at every power-up, as the seed asks."""
    return with_calibration(profile, measure_board_calibration(profile, registry, seed=seed),
                            gyro_startup=pick_device(profile, registry, Quantity.GYRO))
