"""The ``read`` setting of a chip behind an I2C master (``auto``: the master's slave
auto-read; ``one-shot``: the driver's own transactions) is checked against the bus the
profile puts the chip on, before anything is opened."""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml

from imuhal.core.errors import ProfileError
from imuhal.plugins.manager import Registry, load_registry
from imuhal.profile.bundled import bundled_profiles
from imuhal.profile.loader import load_profile, parse_profile

SEED = bundled_profiles()["seed-paraglider-vario.yaml"]
RC = bundled_profiles()["seed-rc-vario.yaml"]


@pytest.fixture(scope="module")
def registry() -> Registry:
    return load_registry()


def _problems(registry: Registry, path: Path, read: object) -> list[str]:
    doc = yaml.safe_load(path.read_text())
    doc["devices"]["mag"]["settings"]["read"] = read
    with pytest.raises(ProfileError) as info:
        parse_profile(yaml.safe_dump(doc, sort_keys=False), "board.yaml", registry)
    return info.value.problems


def test_the_seed_board_reads_its_magnetometer_through_the_auto_read(
        registry: Registry) -> None:
    profile = load_profile(SEED, registry)
    assert profile.devices["mag"].bus == "imu/aux"
    assert profile.devices["mag"].settings["read"] == "auto"


def test_auto_on_a_plain_i2c_bus_is_one_located_line_naming_the_fix(
        registry: Registry) -> None:
    problems = _problems(registry, RC, "auto")
    assert len(problems) == 1
    assert problems[0].startswith("board.yaml:")
    assert "devices.mag.settings.read: 'auto' needs a bus whose master reads the chip on " \
        "its own" in problems[0]
    assert problems[0].endswith("bus 'i2c1' cannot: use read: one-shot (found 'auto')")


def test_one_shot_is_fine_behind_the_master_too(registry: Registry) -> None:
    doc = yaml.safe_load(SEED.read_text())
    doc["devices"]["mag"]["settings"]["read"] = "one-shot"
    profile = parse_profile(yaml.safe_dump(doc, sort_keys=False), "board.yaml", registry)
    assert profile.devices["mag"].settings["read"] == "one-shot"


def test_an_unknown_read_mode_lists_the_allowed_ones(registry: Registry) -> None:
    problems = _problems(registry, SEED, "sideways")
    assert len(problems) == 1
    assert "devices.mag.settings.read: Input should be 'one-shot' or 'auto'" in problems[0]


def test_single_measurements_behind_the_auto_read_are_one_line_naming_the_fix(
        registry: Registry) -> None:
    doc = yaml.safe_load(SEED.read_text())
    doc["devices"]["mag"]["settings"]["mode"] = "single"
    with pytest.raises(ProfileError) as info:
        parse_profile(yaml.safe_dump(doc, sort_keys=False), "board.yaml", registry)
    problems = info.value.problems
    assert len(problems) == 1 and "\n" not in problems[0]
    assert problems[0].startswith("board.yaml:")
    assert "mode 'single' needs the driver to start each measurement" in problems[0]
    assert "use read: one-shot, or mode: continuous" in problems[0]
