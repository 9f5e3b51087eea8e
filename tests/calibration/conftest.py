"""Synthetic raw streams for the calibration tests: the simulator's scenarios seen through
sensor error models with known offsets, scale errors, misalignment, hard and soft iron.

Streams are built straight from the scenario truth and ``SensorErrorModel`` (sensor frame =
body frame), without register-level emulation, so each procedure test is fast; the CLI tests
run the real drivers on an emulated board.
"""

from __future__ import annotations

import json
import math
from collections.abc import Callable
from typing import Any

import numpy as np
import pytest
from tests.support.thermal_learning import ThermalLearningFlight, learning_gps_vario

from imuhal.calibrate.emulated import measure_board_calibration
from imuhal.calibration.model import DeviceCalibration
from imuhal.core.samples import AccelSample, GyroSample, MagSample, Sample
from imuhal.emulation import open_emulated
from imuhal.estimation.outputs import AttitudeEstimate
from imuhal.live.sink import LiveSink
from imuhal.live.snapshot import Snapshotter
from imuhal.plugins.manager import load_registry
from imuhal.profile.bundled import default_profile_path
from imuhal.profile.loader import load_profile
from imuhal.sim.calibration import CalibrationScenario
from imuhal.sim.errors import SensorErrorModel, SensorErrorSpec
from imuhal.sim.scenario import Scenario
from imuhal.sim.world import physical_inputs
from imuhal_filters.common.quat import tilt_error_deg

DPS = math.pi / 180.0
MG = 9.80665e-3

# A board with large, known errors (well beyond a typical part, so recovering them means
# something). Scale errors are fractions; cross-axis terms make the misalignment.
GYRO_BIAS_DPS = (0.8, -1.2, 0.5)
ACCEL_BIAS_MG = (40.0, -25.0, 60.0)
ACCEL_SCALE = (0.02, -0.015, 0.01)
ACCEL_CROSS = ((0.0, 0.01, -0.005), (0.004, 0.0, 0.008), (-0.006, 0.003, 0.0))
HARD_IRON_UT = (20.0, -15.0, 35.0)
SOFT_IRON = ((1.05, 0.03, 0.01), (0.03, 0.97, -0.02), (0.01, -0.02, 1.02))

BOARD_ERRORS = SensorErrorSpec.model_validate({
    "gyro": {"noise_density": 0.005 * DPS, "bias": tuple(b * DPS for b in GYRO_BIAS_DPS)},
    "accel": {"noise_density": 150e-6 * 9.80665, "bias": tuple(b * MG for b in ACCEL_BIAS_MG),
              "scale_factor_error": ACCEL_SCALE, "cross_axis": ACCEL_CROSS},
    "mag": {"noise_std": 0.2, "hard_iron_ut": HARD_IRON_UT, "soft_iron": SOFT_IRON},
})


def make_stream(scenario: Scenario, spec: SensorErrorSpec = BOARD_ERRORS, *, t0: float = 0.0,
                t1: float | None = None, rate_hz: float = 250.0, mag_every: int = 3,
                seed: int = 11, device: str = "imu",
                transform: Callable[[float, Any], Any] | None = None) -> list[Sample]:
    """Raw sensor-frame samples: accel and gyro at ``rate_hz``, mag every ``mag_every``-th
    step. ``transform(t_s, inputs)`` may alter the measured inputs (e.g. a disturbance)."""
    model = SensorErrorModel(spec, seed=seed)
    period = 1.0 / rate_hz
    end = t1 if t1 is not None else getattr(scenario, "default_duration_s", 60.0)
    out: list[Sample] = []
    for i, t in enumerate(np.arange(t0, end, period)):
        meas = model.apply(float(t), physical_inputs(scenario.truth(float(t))), period)
        if transform is not None:
            meas = transform(float(t), meas)
        t_ns = round(t * 1e9)
        out.append(AccelSample(t_ns=t_ns, device=device, accel_m_s2=meas.specific_force_m_s2))
        out.append(GyroSample(t_ns=t_ns, device=device, gyro_rad_s=meas.angular_rate_rad_s))
        if i % mag_every == 0:
            out.append(MagSample(t_ns=t_ns, device=device, mag_ut=meas.magnetic_field_ut))
    return out


@pytest.fixture(scope="session")
def calibration_scenario() -> CalibrationScenario:
    return CalibrationScenario(seed=3)


@pytest.fixture(scope="session")
def calibration_run(calibration_scenario: CalibrationScenario) -> list[Sample]:
    """The whole calibration scenario (six positions, then the figure of 8) on the board."""
    return make_stream(calibration_scenario)


@pytest.fixture(scope="session")
def gps_vario_calibration() -> dict[str, DeviceCalibration]:
    """The accelerometer and magnetometer records the stored seed-gps-vario's emulated board
    (seed 1) measures flying the calibration scenario: one calibration run, which several
    files check things against."""
    registry = load_registry()
    stored = load_profile(default_profile_path().parent / "seed-gps-vario.yaml", registry)
    return measure_board_calibration(stored, registry, seed=1)


@pytest.fixture(scope="session")
def thermal_learning_flight(
        gps_vario_calibration: dict[str, DeviceCalibration]) -> ThermalLearningFlight:
    """One flight shared by the accelerometer-offset and hard-iron tests: each asserts its own
    things about it, and flying it once per test was the slowest part of the suite."""
    registry = load_registry()
    sink = LiveSink()
    tilt: list[float] = []
    with open_emulated(learning_gps_vario(registry), registry, scenario="thermal",
                       seed=1) as pipeline:
        snap = Snapshotter(sink, pipeline)
        world = pipeline.board.scenario  # type: ignore[union-attr]  # an emulated board
        for event in pipeline.events(30.0):
            sink.handle(event)
        mag_health = json.loads(json.dumps(snap.snapshot()["health"]["mag"]))
        for event in pipeline.events(60.0):
            sink.handle(event)
            if (isinstance(event, AttitudeEstimate) and event.source == "ahrs"
                    and event.t_ns >= 60e9):
                truth = world.truth(event.t_ns / 1e9).q_body_to_ned
                tilt.append(tilt_error_deg(event.q_body_to_ned,
                                           tuple(float(v) for v in truth)))
        state = json.loads(json.dumps(snap.snapshot(), allow_nan=False))
        imu_cal = pipeline.devices["imu"].calibration
        accel_status = pipeline.summary().learned["imu accel"]
        words = pipeline.summary().describe()
        for event in pipeline.events(30.0):
            sink.handle(event)
        mag_cal = pipeline.devices["mag"].calibration
        mag_status = pipeline.summary().learned["mag"]
    return ThermalLearningFlight(
        mag_health_at_30_s=mag_health, state_at_90_s=state, tilt_60_to_90_s_deg=tilt,
        imu_calibration_at_90_s=imu_cal, accel_status_at_90_s=accel_status,
        summary_at_90_s=words, mag_calibration_at_120_s=mag_cal,
        mag_status_at_120_s=mag_status,
        reference=gps_vario_calibration)
