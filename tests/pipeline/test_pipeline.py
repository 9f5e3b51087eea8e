"""The pipeline polls on one clock, processes every sample the same way, feeds estimators
only valid body-frame samples, counts what it flags, and keeps running through faults."""

from __future__ import annotations

import itertools
import math
import textwrap

import pytest

from imuhal.core.samples import AccelSample, Frame, PressureSample, SampleFlag
from imuhal.emulation import open_emulated
from imuhal.emulation.faults import BusErrors, ChipAbsent, WildValue
from imuhal.estimation.outputs import VerticalEstimate
from imuhal.pipeline import CallbackSink, Pipeline
from imuhal.plugins.manager import Registry
from imuhal.profile.loader import parse_profile

PROFILE = """\
schema_version: 1
name: pipeline-test
buses:
  i2c1: {kind: i2c, device: /dev/i2c-1}
devices:
  acc:
    driver: tc3
    bus: i2c1
    address: 0x19
    mount: "-Y-X-Z"
    settings: {odr_hz: 50}
estimators:
  rec: {estimator: recorder}
"""


def _open(registry: Registry, text: str = PROFILE, **kw: object) -> Pipeline:
    profile = parse_profile(textwrap.dedent(text), "test.yaml", registry)
    return open_emulated(profile, registry, scenario="thermal", **kw)  # type: ignore[arg-type]


def test_samples_arrive_at_the_configured_rate_in_time_order(registry: Registry) -> None:
    with _open(registry) as p:
        times = [e.t_ns for e in p.events(1.0) if isinstance(e, AccelSample)]
    assert len(times) == 50
    assert all(b - a == 20_000_000 for a, b in itertools.pairwise(times))


def test_vectors_leave_the_pipeline_in_the_ned_body_frame(registry: Registry) -> None:
    with _open(registry) as p:
        accel = next(e for e in p.events(1.0) if isinstance(e, AccelSample))
    assert accel.frame is Frame.BODY_NED
    # the thermal scenario starts level and at rest: specific force (0, 0, -g), 1 mg LSB
    assert accel.accel_m_s2 == pytest.approx((0.0, 0.0, -9.80665), abs=0.01)


def test_estimates_follow_the_samples_they_came_from(registry: Registry) -> None:
    with _open(registry) as p:
        events = list(p.events(0.1))
    kinds = [type(e).__name__ for e in events]
    assert kinds[:3] == ["AccelSample", "PressureSample", "VerticalEstimate"]


def test_a_nan_sample_is_flagged_counted_and_never_fused(registry: Registry) -> None:
    """Issue 9 item 9."""
    nan = WildValue(device="acc", channel="pressure", value=math.nan, start_s=0.0, end_s=1.0)
    with _open(registry, faults=[nan]) as p:
        events = list(p.events(0.2))
        recorder = p.estimators[0].estimator
    bad = [e for e in events if isinstance(e, PressureSample)]
    assert bad and all(SampleFlag.NAN in e.flags for e in bad)
    assert not any(isinstance(s, PressureSample) for s in recorder.seen)
    assert p.summary().flagged["acc"]["NAN"] == len(bad)


def test_a_bus_error_is_counted_and_the_device_recovers(registry: Registry) -> None:
    fault = BusErrors(device="acc", start_s=0.1, end_s=0.1005, rate=1.0)
    with _open(registry, faults=[fault]) as p:
        events = list(p.events(1.0))
    summary = p.summary()
    assert summary.bus_errors["acc"] == p.board.faults.log.injected["acc"]["bus_errors"] >= 1
    assert sum(isinstance(e, AccelSample) for e in events) >= 48
    assert p.devices["acc"].driver.health.reconfigurations == 1


def test_an_unrecoverable_device_does_not_stop_the_others(registry: Registry) -> None:
    text = PROFILE.replace("estimators:", """  acc2:
    driver: tc3
    bus: i2c1
    address: 0x18
estimators:""")
    with _open(registry, text, faults=[ChipAbsent(device="acc2", start_s=0.001)]) as p:
        events = list(p.events(1.0))
    assert sum(isinstance(e, AccelSample) and e.device == "acc" for e in events) == 50
    assert any("acc2: recovery failed" in w for w in p.warnings)


def test_stored_calibration_is_applied_in_the_sensor_frame(registry: Registry) -> None:
    text = PROFILE.replace("    settings: {odr_hz: 50}\n", """    settings: {odr_hz: 50}
    calibration:
      accel: {offset_m_s2: [0.0, 0.0, 1.0], scale: [1.0, 1.0, 2.0]}
""")
    with _open(registry, text) as p:
        accel = next(e for e in p.events(0.1) if isinstance(e, AccelSample))
    # chip z reads +g; corrected = 2 * (g - 1); body z = -chip z
    assert accel.accel_m_s2[2] == pytest.approx(-2 * (9.80665 - 1.0), abs=0.02)


def test_calibration_bound_to_another_chip_is_reported_not_applied(registry: Registry) -> None:
    text = PROFILE.replace("    settings: {odr_hz: 50}\n", """    settings: {odr_hz: 50}
    calibration:
      accel:
        offset_m_s2: [0.0, 0.0, 1.0]
        binding: {driver: tc3, bus: i2c1, address: 0x18, identity: WHO_AM_I=0x5A}
""")
    with _open(registry, text) as p:
        accel = next(e for e in p.events(0.1) if isinstance(e, AccelSample))
    assert accel.accel_m_s2[2] == pytest.approx(-9.80665, abs=0.02)
    assert any("NOT applied" in w and "0x18" in w for w in p.warnings)


def test_estimator_inputs_restrict_what_it_sees(registry: Registry) -> None:
    text = PROFILE.replace("rec: {estimator: recorder}", "rec: {estimator: recorder, inputs: []}")
    with _open(registry, text) as p:
        list(p.events(0.2))
        assert p.estimators[0].estimator.seen == []


def test_a_callback_sink_receives_every_event(registry: Registry) -> None:
    got: list[object] = []
    with _open(registry) as p:
        summary = p.run(0.5, [CallbackSink(got.append, estimates_only=True)])
    assert got and all(isinstance(e, VerticalEstimate) for e in got)
    assert summary.estimates["rec"] == len(got)


def test_a_run_is_deterministic_for_a_seed(registry: Registry) -> None:
    def once() -> list[object]:
        with _open(registry, seed=3) as p:
            return list(p.events(0.5))

    assert once() == once()


def test_uncalibrated_mode_yields_raw_sensor_frame_samples(registry: Registry) -> None:
    text = PROFILE.replace("    settings: {odr_hz: 50}\n", """    settings: {odr_hz: 50}
    calibration:
      accel: {offset_m_s2: [0.0, 0.0, 1.0]}
""")
    with _open(registry, text, calibrated=False) as p:
        events = list(p.events(0.1))
    accel = next(e for e in events if isinstance(e, AccelSample))
    assert accel.frame is Frame.SENSOR
    assert accel.accel_m_s2[2] == pytest.approx(9.80665, abs=0.01)  # chip z up, uncorrected
    assert not any(isinstance(e, VerticalEstimate) for e in events)
