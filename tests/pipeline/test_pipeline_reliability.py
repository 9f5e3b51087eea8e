"""The pipeline survives its buses and keeps validity a contract: faults are contained to
their device and counted, start-up tells a glitch from a wrong chip, optional devices join
later, runs continue across ``events()`` calls, and estimators see one fusion order.
Faults come through the fault-injection interface (imuhal.emulation.faults)."""

from __future__ import annotations

import math
import textwrap

import pytest

from imuhal.core.errors import DeviceNotFoundError
from imuhal.core.samples import AccelSample, PressureSample, Sample, SampleFlag
from imuhal.emulation import open_emulated
from imuhal.emulation.faults import AllZeros, BusErrors, BusOSError, ChipAbsent, LatePolls
from imuhal.estimation.ordering import fusion_order
from imuhal.pipeline import Pipeline
from imuhal.pipeline.processing import validity_flags
from imuhal.plugins.manager import Registry
from imuhal.profile.loader import parse_profile

PROFILE = """\
schema_version: 1
name: reliability-test
buses:
  i2c1: {kind: i2c, device: /dev/i2c-1}
devices:
  acc:
    driver: tc3
    bus: i2c1
    address: 0x19
    settings: {odr_hz: 50}
  acc2:
    driver: tc3
    bus: i2c1
    address: 0x18
    settings: {odr_hz: 100}
estimators:
  rec: {estimator: recorder}
"""


def _open(registry: Registry, text: str = PROFILE, **kw: object) -> Pipeline:
    profile = parse_profile(textwrap.dedent(text), "test.yaml", registry)
    return open_emulated(profile, registry, scenario="thermal", **kw)  # type: ignore[arg-type]


def _accel(events: list[object], device: str) -> list[AccelSample]:
    return [e for e in events if isinstance(e, AccelSample) and e.device == device]


# -- containment ------------------------------------------------------------------------------

def test_an_oserror_from_a_bus_is_contained_to_its_device_and_counted(registry: Registry) -> None:
    """Issue 9 item 4."""
    fault = BusOSError(device="acc2", start_s=0.3, end_s=0.5)
    with _open(registry, faults=[fault]) as p:
        events = list(p.events(1.0))
    summary = p.summary()
    assert summary.bus_errors["acc2"] >= 1
    assert summary.bus_errors["acc"] == 0
    assert len(_accel(events, "acc")) == 50
    assert [e for e in _accel(events, "acc2") if e.t_ns > 0.6e9]  # back after the fault


def test_a_device_that_stays_away_is_reported_once_and_retried(registry: Registry) -> None:
    with _open(registry, faults=[ChipAbsent(device="acc2", start_s=0.2, end_s=0.7)]) as p:
        events = list(p.events(1.5))
    assert sum("acc2: recovery failed" in w for w in p.warnings) == 1
    assert len(_accel(events, "acc")) == 75
    back = [e.t_ns for e in _accel(events, "acc2") if e.t_ns > 0.7e9]
    assert back and back[0] < 0.9e9  # retried every 100 ms at most


# -- start-up -----------------------------------------------------------------------------

def test_startup_rides_through_transient_bus_errors(registry: Registry) -> None:
    """Issue 9 item 5."""
    faults = [BusErrors(device=d, rate=0.3) for d in ("acc", "acc2")]
    for seed in range(10):
        with _open(registry, faults=faults, seed=seed) as p:
            assert all(d.present for d in p.devices.values())


def test_a_wrong_chip_is_reported_at_once_not_retried_as_a_glitch(registry: Registry) -> None:
    """Issue 9 item 5."""
    p = None
    with pytest.raises(DeviceNotFoundError, match="found WHO_AM_I=0x00"):
        p = _open(registry, faults=[AllZeros(device="acc2")])
    assert p is None


def test_an_optional_device_that_is_missing_joins_when_it_appears(registry: Registry) -> None:
    """Issue 9 item 5."""
    text = PROFILE.replace("    settings: {odr_hz: 100}\n",
                           "    settings: {odr_hz: 100}\n    required: false\n")
    with _open(registry, text, faults=[ChipAbsent(device="acc2", end_s=2.5)]) as p:
        assert not p.devices["acc2"].present
        events = list(p.events(4.0))
    assert any("acc2: not found at start-up" in w for w in p.warnings)
    assert any(w.startswith("acc2: found at t=3.0") for w in p.warnings)
    joined = _accel(events, "acc2")
    assert joined and min(e.t_ns for e in joined) >= 3e9 and len(joined) >= 95
    assert len(_accel(events, "acc")) == 200


def test_a_required_device_that_is_missing_stops_the_start(registry: Registry) -> None:
    with pytest.raises(DeviceNotFoundError, match="no answer"):
        _open(registry, faults=[ChipAbsent(device="acc2", end_s=2.5)])


# -- continuation and order -----------------------------------------------------------------

def test_repeated_events_calls_continue_the_run(registry: Registry) -> None:
    """Issue 9 item 1."""
    with _open(registry) as one_go:
        whole = [e for e in one_go.events(1.0) if isinstance(e, Sample)]
    with _open(registry) as pieces:
        parts: list[Sample] = []
        for _ in range(40):
            parts += [e for e in pieces.events(0.025) if isinstance(e, Sample)]
    assert parts == whole


def test_breaking_out_of_events_loses_nothing(registry: Registry) -> None:
    with _open(registry) as one_go:
        whole = [e for e in one_go.events(1.0) if isinstance(e, Sample)]
    with _open(registry) as p:
        got: list[Sample] = []
        for event in p.events(1.0):
            if isinstance(event, Sample):
                got.append(event)
            if len(got) == 20:
                break
        # the rest of the poll the consumer stopped in is gone; the next poll continues
        got += [e for e in p.events(1.0 - p.clock.now_ns() / 1e9) if isinstance(e, Sample)]
    assert [e.t_ns for e in got if e.device == "acc"] == \
        [e.t_ns for e in whole if e.device == "acc"][:len([e for e in got if e.device == "acc"])]


def test_valid_samples_of_a_device_never_go_back_in_time(registry: Registry) -> None:
    """Issue 9 item 6."""
    assert validity_flags(PressureSample(t_ns=5, device="b", pressure_pa=1.0), None, 6) \
        == SampleFlag.OUT_OF_ORDER
    assert validity_flags(PressureSample(t_ns=6, device="b", pressure_pa=1.0), None, 6) \
        == SampleFlag.OK
    faults = [LatePolls(device="acc2", start_s=0.4, end_s=0.45, delay_s=0.1)]
    with _open(registry, faults=faults) as p:
        events = [e for e in p.events(1.0) if isinstance(e, Sample) and e.valid]
    for device in ("acc", "acc2"):
        times = [e.t_ns for e in events if e.device == device and isinstance(e, AccelSample)]
        assert times == sorted(times)


def test_values_beyond_the_configured_full_scale_are_flagged() -> None:
    sample = AccelSample(t_ns=0, device="a", accel_m_s2=(0.0, 300.0, 0.0))
    assert validity_flags(sample, 16 * 9.80665, None) == SampleFlag.OUT_OF_RANGE
    assert validity_flags(sample, 32 * 9.80665, None) == SampleFlag.OK
    nan = AccelSample(t_ns=0, device="a", accel_m_s2=(math.nan, 0.0, 0.0))
    assert validity_flags(nan, 16 * 9.80665, None) == SampleFlag.NAN


@pytest.mark.parametrize("bad", [math.nan, math.inf, -math.inf])
@pytest.mark.parametrize("axis", [0, 1, 2])
def test_a_vector_with_a_non_finite_component_is_flagged_nan_not_out_of_range(
        bad: float, axis: int) -> None:
    vector = [1e308, -0.0, 5e-324]  # finite extremes beside it stay finite
    vector[axis] = bad
    sample = AccelSample(t_ns=0, device="a", accel_m_s2=(vector[0], vector[1], vector[2]))
    assert validity_flags(sample, 16 * 9.80665, None) == SampleFlag.NAN
    assert validity_flags(sample, None, None) == SampleFlag.NAN


def test_a_vector_of_finite_extremes_is_only_out_of_range() -> None:
    sample = AccelSample(t_ns=0, device="a", accel_m_s2=(1e308, -1e308, 5e-324))
    assert validity_flags(sample, 16 * 9.80665, None) == SampleFlag.OUT_OF_RANGE
    assert validity_flags(sample, None, None) == SampleFlag.OK


# -- fusion order -----------------------------------------------------------------------------

@pytest.mark.parametrize("pressure_first", [False, True])
def test_estimators_see_the_same_order_whatever_order_a_driver_emits(
        registry: Registry, pressure_first: bool) -> None:
    first = "true" if pressure_first else "false"
    text = PROFILE.replace("settings: {odr_hz: 50}",
                           f"settings: {{odr_hz: 50, pressure_first: {first}}}")
    with _open(registry, text) as p:
        emitted = [type(e).__name__ for e in p.events(0.1) if isinstance(e, Sample)
                   and e.device == "acc"]
        seen = [type(s).__name__ for s in p.estimators[0].estimator.seen if s.device == "acc"]
    assert emitted[:2] == (["PressureSample", "AccelSample"] if pressure_first
                           else ["AccelSample", "PressureSample"])
    assert seen[:4] == ["AccelSample", "PressureSample"] * 2


def test_fusion_order_is_time_then_accel_mag_pressure_temperature_gyro_then_device() -> None:
    from imuhal.core.samples import GyroSample, MagSample, TemperatureSample
    batch = [GyroSample(t_ns=1, device="a"), TemperatureSample(t_ns=1, device="a"),
             MagSample(t_ns=1, device="m"), AccelSample(t_ns=1, device="b"),
             AccelSample(t_ns=1, device="a"), PressureSample(t_ns=0, device="p")]
    ordered = fusion_order(reversed(batch), {"a": 0, "b": 1, "m": 2, "p": 3})
    assert [(type(s).__name__, s.device) for s in ordered] == [
        ("PressureSample", "p"), ("AccelSample", "a"), ("AccelSample", "b"),
        ("MagSample", "m"), ("TemperatureSample", "a"), ("GyroSample", "a")]
    assert fusion_order(batch, {"a": 0, "b": 1, "m": 2, "p": 3}) == ordered


def test_a_later_different_cause_of_failure_is_reported_too(registry: Registry) -> None:
    faults = [ChipAbsent(device="acc2", start_s=0.2, end_s=0.5),
              BusOSError(device="acc2", start_s=1.0, end_s=1.5)]
    with _open(registry, faults=faults) as p:
        list(p.events(2.0))
    reports = [w for w in p.warnings if w.startswith("acc2: recovery failed")]
    assert len(reports) == 2
    assert "no answer" in reports[0] and "from t=0.2" in reports[0]
    assert "OSError from the bus plugin" in reports[1] and "from t=1.0" in reports[1]
