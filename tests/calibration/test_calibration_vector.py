"""Calibration of any vector quantity: a plugin's quantity (air flow) is calibrated by a
registered procedure, stored in the profile under its name, checked against the device, and
applied by the pipeline in the sensor frame before the mount rotation."""

from __future__ import annotations

import pytest
from tests.support import sensor_plugin
from tests.support.sensor_plugin import ZERO_OFFSET_M_S, AirflowSample

from imuhal.calibrate.session import open_raw_pipeline, run_procedure
from imuhal.calibrate.store import write_device_calibration
from imuhal.calibration.errors import CalibrationError
from imuhal.calibration.model import DeviceCalibration, VectorCalibration
from imuhal.calibration.vector_zero import VectorZeroProcedure, VectorZeroSettings
from imuhal.core.errors import ProfileError
from imuhal.emulation import open_emulated
from imuhal.plugins import builtin_buses, builtin_calibrations, builtin_scenarios
from imuhal.plugins.manager import Registry, load_registry
from imuhal.profile.loader import load_profile, parse_profile

PROFILE = """\
schema_version: 1
name: flow-board
buses:
  i2c1: {kind: i2c, device: /dev/i2c-1}
devices:
  flow:
    driver: af3
    bus: i2c1
    address: 0x28
    mount: "+Y-X+Z"
    settings: {odr_hz: 50}
emulation:
  scenario: static
  sensor_errors: false
"""


@pytest.fixture(scope="module")
def flow_registry() -> Registry:
    return load_registry(entry_point_plugins=False, extra=[
        ("buses", builtin_buses), ("scenarios", builtin_scenarios),
        ("calibrations", builtin_calibrations), ("sensors", sensor_plugin)])


def _samples(values: list[tuple[float, float, float]]) -> list[AirflowSample]:
    return [AirflowSample(t_ns=i, device="flow", airflow_m_s=v) for i, v in enumerate(values)]


def _proc(**settings: float) -> VectorZeroProcedure:
    return VectorZeroProcedure(VectorZeroSettings(**settings), quantity="airflow",
                               device="flow")


def test_vector_zero_stores_the_mean_reading_as_the_offset() -> None:
    values = [(0.5 + 0.01 * (i % 2), -0.25, 0.125) for i in range(20)]
    record = _proc(samples=20).run(_samples(values))
    assert record.offset == pytest.approx((0.505, -0.25, 0.125), abs=1e-12)
    assert record.procedure == "vector-zero" and record.quality["samples"] == 20


def test_vector_zero_measures_again_when_the_readings_move() -> None:
    moving = [(float(i), 0.0, 0.0) for i in range(10)]
    still = [(1.0, 2.0, 3.0)] * 10
    proc = _proc(samples=10, max_std=0.1)
    record = proc.run(_samples(moving + still))
    assert proc.attempts == 2 and record.offset == (1.0, 2.0, 3.0)


def test_vector_zero_without_enough_readings_says_what_is_missing() -> None:
    with pytest.raises(CalibrationError, match="only 3 airflow readings arrived"):
        _proc(samples=10).run(_samples([(0.0, 0.0, 0.0)] * 3))


def test_a_plugin_vector_quantity_is_calibrated_stored_and_applied(
        flow_registry: Registry, tmp_path) -> None:  # type: ignore[no-untyped-def]
    path = tmp_path / "flow.yaml"
    path.write_text(PROFILE)
    profile = load_profile(path, flow_registry)
    with open_raw_pipeline(profile, flow_registry, emulate="static") as raw:
        record = run_procedure(_proc(samples=20), raw, duration_s=2.0)
        binding = raw.calibration_binding("flow")
    # The chip's zero offset, measured in its own frame (exact: whole counts of 1/1024 m/s).
    assert record.offset == ZERO_OFFSET_M_S
    cal = DeviceCalibration().replaced("airflow", record.model_copy(update={"binding": binding}))
    write_device_calibration(path, "flow", cal, flow_registry)

    stored = load_profile(path, flow_registry)
    assert isinstance(stored.devices["flow"].calibration.airflow, VectorCalibration)  # type: ignore[union-attr]
    with open_emulated(stored, flow_registry) as pipeline:
        flows = [e for e in pipeline.events(1.0) if isinstance(e, AirflowSample)]
    assert len(flows) == 50 and not pipeline.warnings
    assert all(s.valid and s.airflow_m_s == (0.0, 0.0, 0.0) for s in flows)


def test_without_calibration_the_offset_is_rotated_into_the_body_frame(
        flow_registry: Registry) -> None:
    profile = parse_profile(PROFILE, "flow.yaml", flow_registry)
    with open_emulated(profile, flow_registry) as pipeline:
        first = next(e for e in pipeline.events(0.1) if isinstance(e, AirflowSample))
    x, y, z = ZERO_OFFSET_M_S
    assert first.airflow_m_s == (y, -x, z)  # mount "+Y-X+Z": body x = chip y, y = -chip x


def test_calibration_for_a_quantity_the_device_does_not_measure_is_a_located_error(
        flow_registry: Registry) -> None:
    text = PROFILE + "    calibration:\n      wind: {offset: [1, 2, 3]}\n"
    text = text.replace("emulation:\n  scenario: static\n  sensor_errors: false\n", "") + \
        "emulation: {scenario: static}\n"
    with pytest.raises(ProfileError) as info:
        parse_profile(text, "flow.yaml", flow_registry)
    assert any("devices.flow.calibration.wind: af3 measures no vector quantity 'wind'; it can "
               "hold calibration for: airflow" in p for p in info.value.problems)
