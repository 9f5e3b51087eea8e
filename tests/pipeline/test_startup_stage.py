"""The start-up gyro stage on its own: fed raw samples, it returns what it measured (or a
warning) and touches nothing else; the pipeline installs what it returns."""

from __future__ import annotations

import numpy as np

from imuhal.calibration.model import (
    CalibrationBinding,
    DeviceCalibration,
    GyroCalibration,
    GyroStartupSettings,
)
from imuhal.core.quantities import Quantity
from imuhal.core.samples import GyroSample
from imuhal.pipeline.startup import GyroStartupStage, startup_settings

BIAS_RAD_S = (0.02, -0.01, 0.005)
BINDING = CalibrationBinding(driver="testchip", bus="i2c0", address=0x68, identity="0x71")


def _still(device: str, n: int, *, seed: int = 1, start_ns: int = 0) -> list[GyroSample]:
    rng = np.random.default_rng(seed)
    return [GyroSample(t_ns=start_ns + i * 4_000_000, device=device,
                       gyro_rad_s=tuple(float(b + rng.normal(0.0, 1e-4)) for b in BIAS_RAD_S))
            for i in range(n)]


def test_only_gyro_devices_that_enable_it_take_part() -> None:
    on = DeviceCalibration(gyro_at_startup=GyroStartupSettings())
    off = DeviceCalibration(gyro_at_startup=GyroStartupSettings(enabled=False))
    settings = startup_settings(
        {"imu": on, "baro": on, "imu2": off, "imu3": None},
        {"imu": (Quantity.GYRO,), "baro": (Quantity.PRESSURE,), "imu2": (Quantity.GYRO,),
         "imu3": (Quantity.GYRO,)})
    assert list(settings) == ["imu"]


def test_a_still_device_returns_offsets_bound_to_its_chip_with_scale_kept() -> None:
    stage = GyroStartupStage({"imu": GyroStartupSettings(samples=50)})
    found = [m for s in _still("imu", 50) if (m := stage.feed(s)) is not None]
    assert stage.done and len(found) == 1 and found[0].warning is None
    stored = DeviceCalibration(gyro=GyroCalibration(offset_rad_s=(1.0, 1.0, 1.0),
                                                    scale=(1.1, 1.0, 1.0)))
    new = found[0].calibration(stored, BINDING)
    assert new is not None and new.gyro is not None
    assert np.allclose(new.gyro.offset_rad_s, BIAS_RAD_S, atol=1e-4)
    assert new.gyro.scale == (1.1, 1.0, 1.0)
    assert (new.gyro.procedure, new.gyro.binding) == ("gyro-at-startup", BINDING)
    assert stored.gyro is not None and stored.gyro.offset_rad_s == (1.0, 1.0, 1.0)


def test_samples_of_other_devices_are_ignored() -> None:
    stage = GyroStartupStage({"imu": GyroStartupSettings(samples=10)})
    assert all(stage.feed(s) is None for s in _still("other", 30))
    assert not stage.done


def test_a_device_that_never_stays_still_returns_a_warning_and_keeps_the_stored_record(
        ) -> None:
    stage = GyroStartupStage({"imu": GyroStartupSettings(samples=10, max_attempts=1)})
    rng = np.random.default_rng(3)
    moving = [GyroSample(t_ns=i * 4_000_000, device="imu",
                         gyro_rad_s=tuple(float(x) for x in rng.normal(0.0, 1.0, 3)))
              for i in range(10)]
    found = [m for s in moving if (m := stage.feed(s)) is not None]
    assert stage.done and len(found) == 1
    assert found[0].warning is not None and "imu: start-up gyro offsets not measured" in \
        found[0].warning
    stored = DeviceCalibration(gyro=GyroCalibration(offset_rad_s=(0.1, 0.1, 0.1)))
    assert found[0].calibration(stored, BINDING) is stored
