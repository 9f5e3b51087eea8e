"""The seed board keeps running through transient faults of its real drivers: each fault is
detected, flagged or counted, the device is brought back, and the other devices never stop.
Every fault is injected mid-flight through the fault-injection interface
(imuhal.emulation.faults).

"Brought back" means reading the truth again, not only producing samples: after each fault,
the valid samples of the second half of the run are checked against the scenario's truth
(accelerometer 1.5 m/s^2, gyroscope 0.05 rad/s, pressure 200 Pa: the datasheet errors of the
uncalibrated chips with margin, as in test_bundled_profiles.py; magnetometer 25 uT: the seed
board's HMC5883L has 11.5 uT of hard iron and 2 uT offsets, and a reading of zero on the
41 uT field must fail) and the vario's climb rate within 0.5 m/s.
"""

from __future__ import annotations

import numpy as np
import pytest

from imuhal.core.samples import (
    AccelSample,
    GyroSample,
    MagSample,
    PressureSample,
    Sample,
    VectorSample,
)
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
from imuhal.profile.bundled import default_profile_path
from imuhal.profile.loader import load_profile

SEED = 3
BOUND = {AccelSample: 1.5, GyroSample: 0.05, MagSample: 25.0, PressureSample: 200.0}
CLIMB_BOUND_M_S = 0.5


@pytest.fixture(scope="module")
def registry() -> Registry:
    return load_registry()


def _assert_on_truth(registry: Registry, events: list[object],
                     devices: tuple[str, ...] = ("imu", "mag", "baro")) -> None:
    """The valid samples of ``devices`` and the vario's estimates in the second half of
    ``events`` read the truth."""
    truth_of = registry.scenarios.get("thermal")(None, seed=SEED).truth
    tail = events[len(events) // 2:]
    checked = dict.fromkeys(BOUND, 0)
    for e in tail:
        if isinstance(e, Sample) and e.valid and type(e) in BOUND and e.device in devices:
            truth = truth_of(e.t_ns / 1e9)
            if isinstance(e, VectorSample):
                want = {AccelSample: truth.specific_force_body_m_s2,
                        GyroSample: truth.angular_rate_body_rad_s,
                        MagSample: truth.magnetic_field_body_ut}[type(e)]
                err = float(np.linalg.norm(np.asarray(e.vector) - want))
            else:
                err = abs(e.pressure_pa - truth.pressure_pa)
            assert err <= BOUND[type(e)], (e, err)
            checked[type(e)] += 1
        elif isinstance(e, VerticalEstimate) and e.source == "vario":
            true_climb = -truth_of(e.t_ns / 1e9).velocity_ned_m_s[2]
            assert abs(e.climb_m_s - true_climb) <= CLIMB_BOUND_M_S, e
    expected = {GyroSample, AccelSample} if "imu" in devices else set()
    expected |= {MagSample} if "mag" in devices else set()
    expected |= {PressureSample} if "baro" in devices else set()
    assert all(checked[kind] for kind in expected), checked


def _open(registry: Registry, *faults: FaultSpec) -> Pipeline:
    profile = load_profile(default_profile_path(), registry)
    return open_emulated(profile, registry, scenario="thermal", seed=SEED, faults=faults)


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
    _assert_on_truth(registry, after)


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
    _assert_on_truth(registry, events)


def test_stuck_data_ready_is_flagged_stale_then_cleared_by_a_reset(registry: Registry) -> None:
    pipeline = _open(registry, StuckDataReady(device="imu", start_s=1.0))
    list(pipeline.events(1.0))
    events = list(pipeline.events(2.0))
    assert pipeline.summary().flagged["imu"].get("STALE", 0) > 0
    assert [e for e in _valid(events, AccelSample, "imu") if e.t_ns >= 2.5e9]
    _assert_on_truth(registry, events)


def test_a_barometer_reset_mid_conversion_costs_one_stale_sample(registry: Registry) -> None:
    pipeline = _open(registry, ChipReset(device="baro", start_s=1.0))
    list(pipeline.events(1.0))
    events = list(pipeline.events(1.0))
    assert pipeline.summary().flagged["baro"].get("STALE", 0) >= 1
    assert len(_valid(events, PressureSample, "baro")) >= 45
    _assert_on_truth(registry, events)


def test_a_magnetometer_that_vanishes_leaves_the_rest_running(registry: Registry) -> None:
    pipeline = _open(registry, ChipAbsent(device="mag", start_s=1.0))
    list(pipeline.events(1.0))
    events = list(pipeline.events(2.0))
    mag_warnings = [w for w in pipeline.warnings if w.startswith("mag:")]
    assert 1 <= len(mag_warnings) <= 2  # reported once per kind, not at every retry
    assert len(_valid(events, GyroSample, "imu")) > 450
    assert len(_valid(events, PressureSample, "baro")) > 90
    # The others only: the HMC5883L's driver still marks what it reads from the vanished chip
    # behind the master valid (1 count on each axis), which issue 9 (in-driver validity) is
    # about; the magnetometer bound above fails on it.
    _assert_on_truth(registry, events, devices=("imu", "baro"))
