"""``imuhal profile schema``: the JSON Schema editors check profiles against while typing."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import pytest
import yaml

from imuhal.cli.main import main
from imuhal.plugins.manager import Registry, load_registry
from imuhal.profile.bundled import bundled_profiles
from imuhal.profile.json_schema import profile_schema

jsonschema = pytest.importorskip("jsonschema", reason="jsonschema is in the test extra")


@pytest.fixture(scope="module")
def full_registry() -> Registry:
    return load_registry()


@pytest.fixture(scope="module")
def validator(full_registry: Registry) -> Any:
    schema = profile_schema(full_registry)
    jsonschema.Draft202012Validator.check_schema(schema)
    return jsonschema.Draft202012Validator(schema)


def _gy91() -> dict[str, Any]:
    return yaml.safe_load(Path("profiles/gy91.yaml").read_text())


@pytest.mark.parametrize("profile", list(bundled_profiles().values()), ids=lambda p: p.stem)
def test_every_bundled_profile_is_valid_against_the_schema(validator: Any,
                                                           profile: Path) -> None:
    errors = [e.message for e in validator.iter_errors(yaml.safe_load(profile.read_text()))]
    assert errors == []


def test_a_typo_in_a_driver_setting_is_rejected(validator: Any) -> None:
    doc = _gy91()
    doc["devices"]["imu"]["settings"]["gyro_rang_dps"] = 500
    assert not validator.is_valid(doc)


def test_a_typo_in_an_estimator_setting_is_rejected(validator: Any) -> None:
    doc = _gy91()
    doc["estimators"]["ahrs"].setdefault("settings", {})["tau_acc_ss"] = 3.0  # tau_acc_s
    assert not validator.is_valid(doc)


def test_a_typo_in_a_top_level_key_is_rejected(validator: Any) -> None:
    doc = _gy91()
    doc["estimator"] = doc.pop("estimators")
    errors = list(validator.iter_errors(doc))
    assert any("estimator" in e.message for e in errors)


def test_a_value_the_chip_cannot_do_is_rejected(validator: Any) -> None:
    doc = _gy91()
    doc["devices"]["imu"]["settings"]["gyro_range_dps"] = 300  # 250, 500, 1000, 2000 only
    assert not validator.is_valid(doc)
    doc["devices"]["imu"]["settings"]["gyro_range_dps"] = 1000
    assert validator.is_valid(doc)


def test_each_output_section_is_checked_against_its_output(validator: Any) -> None:
    doc = _gy91()
    doc["outputs"] = {"mcap": {"frame_id": "imu_link"}, "mavlink": {"system_id": 7},
                      "mqtt": {"board": "glider-7", "decimate": {"imu/*": 10}}}
    assert validator.is_valid(doc)
    for wrong in ({"mqtt": {"bord": "glider-7"}},  # a typo in a plugin sink's setting
                  {"mavlink": {"system_id": 0}},  # a value the built-in output refuses
                  {"kafka": {}},  # no installed sink of that name
                  {"ros": {"frame_id": "imu_link"}}):  # the built-in output is mcap
        assert not validator.is_valid({**doc, "outputs": wrong}), wrong


def test_each_device_is_checked_against_the_driver_it_names(validator: Any) -> None:
    doc = _gy91()
    doc["devices"]["baro"]["settings"] = {"gyro_range_dps": 500}  # an MPU-9250 setting
    assert not validator.is_valid(doc)


def test_profile_schema_prints_the_schema_and_one_drivers_settings(
        capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["profile", "schema"]) == 0
    schema = json.loads(capsys.readouterr().out)
    assert schema["$schema"].endswith("2020-12/schema")
    assert main(["profile", "schema", "--driver", "bmp280"]) == 0
    settings = json.loads(capsys.readouterr().out)
    assert "pressure_oversampling" in settings["properties"]
    assert settings["additionalProperties"] is False


def test_each_setting_carries_its_documentation_for_editor_hovers(full_registry: Registry
                                                                  ) -> None:
    definitions = profile_schema(full_registry)["$defs"]
    assert "spidev" in definitions["SpiBus"]["properties"]["bus"]["description"]
    assert "kernel" in definitions["IIODriverSettings"]["properties"]["name"]["description"]
