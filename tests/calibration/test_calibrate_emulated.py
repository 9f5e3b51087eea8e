"""imuhal.calibrate.emulated: an emulated board calibrated by imuhal's own procedures."""

from __future__ import annotations

import numpy as np
import pytest

from imuhal.calibrate.emulated import calibrated_board, with_calibration
from imuhal.core.samples import AccelSample, MagSample
from imuhal.emulation import open_emulated
from imuhal.plugins.manager import Registry, load_registry
from imuhal.profile.bundled import default_profile_path
from imuhal.profile.loader import load_profile
from imuhal.profile.model import BoardProfile


@pytest.fixture(scope="module")
def registry() -> Registry:
    return load_registry()


def _rest_errors(profile: BoardProfile, registry: Registry) -> tuple[float, float]:
    """Mean accelerometer (m/s^2) and magnetometer (uT) error against the truth at rest,
    seed 1, datasheet sensor errors."""
    with open_emulated(profile, registry, scenario="static", seed=1,
                       sensor_errors=True) as pipeline:
        events = list(pipeline.events(6.0))
        assert pipeline.board is not None
        truth = pipeline.board.truth_at(events[-1].t_ns)  # at rest: the same all along
    accel = [e.accel_m_s2 for e in events if isinstance(e, AccelSample) and e.valid]
    mag = [e.mag_ut for e in events if isinstance(e, MagSample) and e.valid]
    assert len(accel) > 500 and len(mag) > 100
    return (float(np.linalg.norm(np.mean(accel, axis=0) - truth.specific_force_body_m_s2)),
            float(np.linalg.norm(np.mean(mag, axis=0) - truth.magnetic_field_body_ut)))


def test_the_calibrated_seed_board_measures_gravity_and_the_field_where_the_raw_one_is_off(
        registry: Registry) -> None:
    seed_board = load_profile(default_profile_path(), registry).model_copy(
        update={"estimators": {}})
    calibrated = calibrated_board(seed_board, registry, seed=1)
    assert calibrated.devices["imu"].calibration is not None
    assert calibrated.devices["imu"].calibration.gyro_at_startup is not None
    raw_accel, raw_mag = _rest_errors(with_calibration(seed_board, {}, gyro_startup="imu"),
                                      registry)
    accel, mag = _rest_errors(calibrated, registry)
    assert raw_accel > 0.3 and raw_mag > 10.0  # the chips' datasheet errors, uncorrected
    assert accel < 0.06 and mag < 1.0  # measured 0.03 m/s^2, 0.13 uT
