"""The seed board keeps running through transient faults of its real drivers: each fault is
detected, flagged or counted, the device is brought back, and the other devices never stop.
Every fault is injected mid-flight through the fault-injection interface
(imuhal.emulation.faults)."""

from __future__ import annotations

import pytest

from imuhal.core.samples import AccelSample, GyroSample, MagSample, PressureSample, Sample
from imuhal.emulation import open_emulated
from imuhal.emulation.faults import (
    BusErrors,
    ChipAbsent,
    ChipReset,
    FaultSpec,
    StuckDataReady,
)
from imuhal.estimation.outputs import VerticalEstimate
from imuhal.pipeline import Pipeline
from imuhal.plugins.manager import Registry, load_registry
from imuhal.profile.loader import load_profile
from imuhal.profiles_dir import default_profile_path


@pytest.fixture(scope="module")
def registry() -> Registry:
    return load_registry()


def _open(registry: Registry, *faults: FaultSpec) -> Pipeline:
    profile = load_profile(default_profile_path(), registry)
    return open_emulated(profile, registry, scenario="thermal", seed=3, faults=faults)


def _valid(events: list[object], kind: type, device: str) -> list[Sample]:
    return [e for e in events if isinstance(e, kind) and e.device == device and e.valid]


def test_a_silent_imu_reset_is_detected_and_the_imu_reconfigured(registry: Registry) -> None:
    pipeline = _open(registry, ChipReset(device="imu", start_s=1.0))
    list(pipeline.events(1.0))
    after = list(pipeline.events(2.0))
    health = pipeline.devices["imu"].driver.health
    assert health.resets_detected == 1
    last_second = [e for e in _valid(after, GyroSample, "imu") if e.t_ns >= 2e9]
    assert len(last_second) >= 240  # back at 250 Hz
    assert _valid(after, PressureSample, "baro")  # the barometer never stopped


def test_bus_errors_on_the_shared_spi_bus_are_counted_and_recovered(registry: Registry) -> None:
    pipeline = _open(registry, BusErrors(device="imu", start_s=1.0, end_s=1.5, rate=0.02),
                     BusErrors(device="baro", start_s=1.0, end_s=1.5, rate=0.05))
    list(pipeline.events(1.0))
    events = list(pipeline.events(2.0))
    summary = pipeline.summary()
    assert summary.bus_errors["baro"] == pipeline.board.faults.log.injected["baro"]["bus_errors"]
    assert summary.bus_errors["baro"] > 0
    assert summary.warnings == []
    tail = events[len(events) // 2:]
    for kind, device in ((GyroSample, "imu"), (MagSample, "mag"), (PressureSample, "baro")):
        assert _valid(tail, kind, device), device
    assert any(isinstance(e, VerticalEstimate) for e in tail)


def test_stuck_data_ready_is_flagged_stale_then_cleared_by_a_reset(registry: Registry) -> None:
    pipeline = _open(registry, StuckDataReady(device="imu", start_s=1.0))
    list(pipeline.events(1.0))
    events = list(pipeline.events(2.0))
    assert pipeline.summary().flagged["imu"].get("STALE", 0) > 0
    assert [e for e in _valid(events, AccelSample, "imu") if e.t_ns >= 2.5e9]


def test_a_barometer_reset_mid_conversion_costs_one_stale_sample(registry: Registry) -> None:
    pipeline = _open(registry, ChipReset(device="baro", start_s=1.0))
    list(pipeline.events(1.0))
    events = list(pipeline.events(1.0))
    assert pipeline.summary().flagged["baro"].get("STALE", 0) >= 1
    assert len(_valid(events, PressureSample, "baro")) >= 45


def test_a_magnetometer_that_vanishes_leaves_the_rest_running(registry: Registry) -> None:
    pipeline = _open(registry, ChipAbsent(device="mag", start_s=1.0))
    list(pipeline.events(1.0))
    events = list(pipeline.events(2.0))
    mag_warnings = [w for w in pipeline.warnings if w.startswith("mag:")]
    assert 1 <= len(mag_warnings) <= 2  # reported once per kind, not at every retry
    assert len(_valid(events, GyroSample, "imu")) > 450
    assert len(_valid(events, PressureSample, "baro")) > 90
