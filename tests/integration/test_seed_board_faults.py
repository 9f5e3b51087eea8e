"""The seed board keeps running through transient faults of its real drivers: each fault is
detected, flagged or counted, the device is brought back, and the other devices never stop.
Every fault is injected into the register-level emulators mid-flight."""

from __future__ import annotations

from collections.abc import Iterator

import pytest

from imuhal.core.samples import AccelSample, GyroSample, MagSample, PressureSample, Sample
from imuhal.emulation import open_emulated
from imuhal.estimation.outputs import VerticalEstimate
from imuhal.pipeline import Pipeline
from imuhal.plugins.manager import Registry, load_registry
from imuhal.profile.loader import load_profile
from imuhal.profiles_dir import default_profile_path


@pytest.fixture(scope="module")
def registry() -> Registry:
    return load_registry()


@pytest.fixture
def pipeline(registry: Registry) -> Iterator[Pipeline]:
    profile = load_profile(default_profile_path(), registry)
    with open_emulated(profile, registry, scenario="thermal", seed=3) as p:
        yield p


def _valid(events: list[object], kind: type, device: str) -> list[Sample]:
    return [e for e in events if isinstance(e, kind) and e.device == device and e.valid]


def test_a_silent_imu_reset_is_detected_and_the_imu_reconfigured(pipeline: Pipeline) -> None:
    list(pipeline.events(1.0))
    pipeline.board.emulators["imu"].silent_reset()
    after = list(pipeline.events(2.0))
    health = pipeline.devices["imu"].driver.health
    assert health.resets_detected == 1
    last_second = [e for e in _valid(after, GyroSample, "imu") if e.t_ns >= 2e9]
    assert len(last_second) >= 240  # back at 250 Hz
    assert _valid(after, PressureSample, "baro")  # the barometer never stopped


def test_bus_errors_on_the_shared_spi_bus_are_counted_and_recovered(pipeline: Pipeline) -> None:
    list(pipeline.events(1.0))
    pipeline.buses["spi0"].fail_transfers({1, 50, 200})
    events = list(pipeline.events(2.0))
    summary = pipeline.summary()
    assert sum(summary.bus_errors.values()) == 3
    assert summary.warnings == []
    tail = events[len(events) // 2:]
    for kind, device in ((GyroSample, "imu"), (MagSample, "mag"), (PressureSample, "baro")):
        assert _valid(tail, kind, device), device
    assert any(isinstance(e, VerticalEstimate) for e in tail)


def test_stuck_data_ready_is_flagged_stale_then_cleared_by_a_reset(pipeline: Pipeline) -> None:
    list(pipeline.events(1.0))
    pipeline.board.emulators["imu"].stuck_data_ready = True
    events = list(pipeline.events(2.0))
    assert pipeline.summary().flagged["imu"].get("STALE", 0) > 0
    assert [e for e in _valid(events, AccelSample, "imu") if e.t_ns >= 2.5e9]


def test_a_barometer_reset_mid_conversion_costs_one_stale_sample(pipeline: Pipeline) -> None:
    list(pipeline.events(1.0))
    pipeline.board.emulators["baro"].silent_reset()
    events = list(pipeline.events(1.0))
    assert pipeline.summary().flagged["baro"].get("STALE", 0) >= 1
    assert len(_valid(events, PressureSample, "baro")) >= 45


def test_a_magnetometer_that_vanishes_leaves_the_rest_running(pipeline: Pipeline) -> None:
    list(pipeline.events(1.0))
    pipeline.board.emulators["mag"].absent = True
    events = list(pipeline.events(2.0))
    mag_warnings = [w for w in pipeline.warnings if w.startswith("mag:")]
    assert 1 <= len(mag_warnings) <= 2  # reported once per kind, not at every retry
    assert len(_valid(events, GyroSample, "imu")) > 450
    assert len(_valid(events, PressureSample, "baro")) > 90
