"""``read: auto`` on the AK8963 behind an MPU-9250 is checked against the MPU's aux mode
before anything is opened: slave 0 exists only in master mode; in bypass the aux bus is the
host bus."""

from __future__ import annotations

import pytest
import yaml

from imuhal.core.errors import ProfileError
from imuhal.plugins.manager import Registry, load_registry
from imuhal.profile.bundled import bundled_profiles
from imuhal.profile.loader import load_profile, parse_profile

GPS = bundled_profiles()["seed-gps-vario.yaml"]
GY91 = bundled_profiles()["gy91.yaml"]


@pytest.fixture(scope="module")
def registry() -> Registry:
    return load_registry()


def _parse(registry: Registry, doc: dict[str, object]) -> object:
    return parse_profile(yaml.safe_dump(doc, sort_keys=False), "board.yaml", registry)


def test_the_gps_vario_auto_reads_its_ak8963_and_the_gy91_uses_the_bypass(
        registry: Registry) -> None:
    assert load_profile(GPS, registry).devices["mag"].settings["read"] == "auto"
    gy91 = load_profile(GY91, registry)
    assert gy91.devices["imu"].settings["aux"] == "bypass"
    assert gy91.devices["mag"].settings.get("read", "one-shot") == "one-shot"


def test_auto_behind_the_bypass_is_one_located_line_naming_the_fix(
        registry: Registry) -> None:
    doc = yaml.safe_load(GY91.read_text())
    doc["devices"]["mag"]["settings"]["read"] = "auto"
    with pytest.raises(ProfileError) as info:
        _parse(registry, doc)
    problems = info.value.problems
    assert len(problems) == 1 and "\n" not in problems[0]
    assert problems[0].startswith("board.yaml:")
    assert "devices.mag.settings.read: 'auto' needs a bus whose master reads the chip" \
        in problems[0]
    assert "aux: master" in problems[0]
    assert problems[0].endswith("bus 'imu/aux' cannot: use read: one-shot (found 'auto')")


def test_the_gy91_can_auto_read_through_the_master_and_the_gps_vario_one_shot(
        registry: Registry) -> None:
    doc = yaml.safe_load(GY91.read_text())
    doc["devices"]["imu"]["settings"]["aux"] = "master"
    doc["devices"]["mag"]["settings"]["read"] = "auto"
    assert _parse(registry, doc).devices["mag"].settings["read"] == "auto"  # type: ignore[attr-defined]
    doc = yaml.safe_load(GPS.read_text())
    doc["devices"]["mag"]["settings"]["read"] = "one-shot"
    assert _parse(registry, doc).devices["mag"].settings["read"] == "one-shot"  # type: ignore[attr-defined]
