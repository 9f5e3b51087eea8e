"""The pipeline collects every device's stream specs and binds them into the estimators fed
by it: limits and periods follow the chip's configuration (read back from its registers), a
hand setting that contradicts its stream is a one-line profile error naming the key."""

from __future__ import annotations

import math
from pathlib import Path

import pytest
import yaml

from imuhal.core.errors import ProfileError
from imuhal.core.quantities import Quantity
from imuhal.core.samples import Frame
from imuhal.core.streams import StreamSpec
from imuhal.emulation.open import open_emulated
from imuhal.pipeline import Pipeline
from imuhal.plugins.manager import Registry, load_registry
from imuhal.profile.loader import parse_profile

PROFILES = Path(__file__).resolve().parents[2] / "profiles"
SEED = "seed-paraglider-vario.yaml"


@pytest.fixture(scope="module")
def registry() -> Registry:
    return load_registry()


def open_profile(registry: Registry, name: str = SEED, **replace: str) -> Pipeline:
    """The bundled profile ``name``, with each ``old -> new`` text replacement applied."""
    text = (PROFILES / name).read_text()
    for old, new in replace.items():
        assert old in text, f"{old!r} is not in {name}"
        text = text.replace(old, new)
    return open_emulated(parse_profile(text, name, registry), registry)


def ahrs_settings(pipeline: Pipeline, name: str = "ahrs") -> object:
    return next(e.estimator.settings for e in pipeline.estimators if e.name == name)


def test_the_pipeline_exposes_each_devices_streams_as_read_back(registry: Registry) -> None:
    pipeline = open_profile(registry)
    gyro = next(s for s in pipeline.streams["imu"] if s.quantity == Quantity.GYRO)
    assert (gyro.rate_hz, gyro.full_scale) == (250, math.radians(500))
    assert {s.quantity for s in pipeline.streams["baro"]} == {Quantity.PRESSURE,
                                                               Quantity.TEMPERATURE}
    assert pipeline.devices["imu"].full_scale[Quantity.GYRO] == gyro.full_scale


def test_the_ahrs_takes_its_period_and_limits_from_the_imu_streams(registry: Registry) -> None:
    s = ahrs_settings(open_profile(registry))
    assert s.sample_period_s == 0.004  # type: ignore[attr-defined]  # exactly 1 / 250 Hz
    assert s.gyro_full_scale_rad_s == pytest.approx(1.1 * math.radians(500))  # type: ignore[attr-defined]
    assert s.accel_full_scale_m_s2 == pytest.approx(1.1 * 4 * 9.80665)  # type: ignore[attr-defined]


def test_the_ahrs_limit_follows_a_gyro_range_changed_in_the_profile(registry: Registry) -> None:
    s = ahrs_settings(open_profile(registry, **{"gyro_range_dps: 500": "gyro_range_dps: 1000"}))
    assert s.gyro_full_scale_rad_s == pytest.approx(1.1 * math.radians(1000))  # type: ignore[attr-defined]


def test_the_ahrs_period_follows_a_gyro_rate_changed_in_the_profile(registry: Registry) -> None:
    s = ahrs_settings(open_profile(registry, **{"gyro_odr_hz: 250": "gyro_odr_hz: 500"}))
    assert s.sample_period_s == 0.002  # type: ignore[attr-defined]


def test_a_hand_limit_below_the_streams_full_scale_is_a_one_line_profile_error(
        registry: Registry) -> None:
    with pytest.raises(ProfileError) as caught:
        open_profile(registry, **{"nominal_airspeed_m_s: 10\n": (
            "nominal_airspeed_m_s: 10\n      gyro_full_scale_rad_s: 5\n")})
    message = str(caught.value)
    assert "\n" not in message
    assert "estimators.ahrs.settings.gyro_full_scale_rad_s" in message
    assert "remove gyro_full_scale_rad_s" in message


def test_a_hand_period_off_the_stream_by_more_than_5_percent_is_an_error(
        registry: Registry) -> None:
    with pytest.raises(ProfileError, match=r"estimators\.ahrs\.settings\.sample_period_s: "
                                           r"0\.005 s contradicts the gyro stream of 'imu' "
                                           r"\(250 Hz"):
        open_profile(registry, **{"nominal_airspeed_m_s: 10\n": (
            "nominal_airspeed_m_s: 10\n      sample_period_s: 0.005\n")})


def test_a_hand_setting_that_agrees_with_the_stream_is_kept(registry: Registry) -> None:
    s = ahrs_settings(open_profile(registry, **{"nominal_airspeed_m_s: 10\n": (
        "nominal_airspeed_m_s: 10\n      sample_period_s: 0.00401\n"
        "      gyro_full_scale_rad_s: 20\n")}))
    assert (s.sample_period_s, s.gyro_full_scale_rad_s) == (0.00401, 20)  # type: ignore[attr-defined]


def stream_bound_settings(registry: Registry) -> set[str]:
    """The settings some registered estimator takes from its streams: those its ``bind``
    changes when fed a gyro and an accelerometer stream unlike every default."""
    streams = (StreamSpec("imu", Quantity.GYRO, Frame.SENSOR, 333.0, full_scale=7.0),
               StreamSpec("imu", Quantity.ACCEL, Frame.SENSOR, 333.0, full_scale=50.0))
    keys: set[str] = set()
    for name in registry.estimators.names():
        estimator = registry.estimators.get(name)({})
        before = estimator.settings.model_dump()
        estimator.bind(streams)
        after = estimator.settings.model_dump()
        keys |= {key for key in before if before[key] != after[key]}
    return keys


def test_no_bundled_profile_gives_a_setting_the_streams_bind(registry: Registry) -> None:
    bound = stream_bound_settings(registry)
    assert bound >= {"sample_period_s", "sensor_rate_hz", "gyro_full_scale_rad_s",
                     "accel_full_scale_m_s2"}
    given = {f"{path.name}: estimators.{name}.settings.{key}"
             for path in sorted(PROFILES.glob("*.yaml"))
             for name, spec in yaml.safe_load(path.read_text())["estimators"].items()
             for key in (spec.get("settings") or {}) if key in bound}
    assert given == set()


def test_freescale_integrates_at_the_gyro_streams_rate(registry: Registry) -> None:
    pipeline = open_profile(registry, **{"  baro-only:": (
        "  fs:\n    estimator: freescale-6dof\n    inputs: [imu]\n  baro-only:")})
    s = ahrs_settings(pipeline, "fs")
    assert s.sensor_rate_hz == 250  # type: ignore[attr-defined]  # not its 200 Hz default


def test_a_freescale_rate_set_by_hand_against_the_stream_is_an_error(
        registry: Registry) -> None:
    with pytest.raises(ProfileError, match=r"estimators\.fs\.settings\.sensor_rate_hz: 200 Hz "
                                           r"contradicts the gyro stream"):
        open_profile(registry, **{"  baro-only:": (
            "  fs:\n    estimator: freescale-6dof\n    inputs: [imu]\n"
            "    settings: {sensor_rate_hz: 200}\n  baro-only:")})


def test_an_estimator_takes_only_the_streams_of_its_inputs(registry: Registry) -> None:
    # fed the magnetometer only, no gyro stream reaches it: its rate keeps its default
    pipeline = open_profile(registry, **{"  baro-only:": (
        "  fs:\n    estimator: freescale-6dof\n    inputs: [mag]\n  baro-only:")})
    assert ahrs_settings(pipeline, "fs").sensor_rate_hz == 200  # type: ignore[attr-defined]


def test_imuhal_run_refuses_a_contradicting_profile_with_exit_2(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from imuhal.cli.main import main

    bad = tmp_path / "bad.yaml"
    bad.write_text((PROFILES / SEED).read_text().replace(
        "nominal_airspeed_m_s: 10\n", "nominal_airspeed_m_s: 10\n      sample_period_s: 0.005\n"))
    assert main(["run", str(bad), "--emulate", "thermal", "--duration", "1", "--quiet"]) == 2
    errors = [line for line in capsys.readouterr().err.splitlines() if "error" in line]
    assert errors == [
        "imuhal: error: seed-paraglider-vario: estimators.ahrs.settings.sample_period_s: "
        "0.005 s contradicts the gyro stream of 'imu' (250 Hz: 0.004 s); remove "
        "sample_period_s (it follows the stream) or change the stream's rate"]


@pytest.mark.parametrize("estimator", ["mahony", "imufilter", "decoupled", "vqf"])
def test_every_ahrs_takes_the_gyro_streams_period(registry: Registry, estimator: str) -> None:
    if estimator == "vqf":
        pytest.importorskip("vqf", reason="the vqf estimator needs the vqf package")
    pipeline = open_profile(registry, **{
        "estimator: madgwick ": f"estimator: {estimator} ",
        "gyro_odr_hz: 250": "gyro_odr_hz: 500",
        "accel_odr_hz: 250": "accel_odr_hz: 500"})
    assert ahrs_settings(pipeline).sample_period_s == 0.002  # type: ignore[attr-defined]
