"""Profile errors name file:line:column, the field path, the value and what is allowed,
and every problem is reported at once."""

from __future__ import annotations

import textwrap
from pathlib import Path

import pytest

from imuhal.core.errors import ProfileError
from imuhal.plugins.manager import Registry
from imuhal.profile.loader import check_profile, load_profile, parse_profile

GOOD = """\
schema_version: 1
name: test-board
buses:
  i2c1: {kind: i2c, device: /dev/i2c-1}
devices:
  acc:
    driver: tc3
    bus: i2c1
    address: 0x19
    mount: "-Y-X-Z"
    settings: {odr_hz: 100}
"""


def _problems(text: str, registry: Registry) -> list[str]:
    with pytest.raises(ProfileError) as info:
        parse_profile(textwrap.dedent(text), "board.yaml", registry)
    return info.value.problems


def test_a_good_profile_loads(registry: Registry) -> None:
    profile = parse_profile(GOOD, "board.yaml", registry)
    assert profile.devices["acc"].address == 0x19


def test_an_unknown_key_is_located_and_lists_the_allowed_keys(registry: Registry) -> None:
    problems = _problems(GOOD.replace("    mount:", "    mounting: x\n    mount:"), registry)
    assert len(problems) == 1
    p = problems[0]
    assert p.startswith("board.yaml:10:5: devices.acc.mounting: unknown key")
    assert "allowed keys: driver, bus, address, mount" in p


def test_a_driver_setting_is_checked_by_the_driver_and_names_allowed_values(
    registry: Registry,
) -> None:
    problems = _problems(GOOD.replace("odr_hz: 100", "odr_hz: 75"), registry)
    assert len(problems) == 1
    assert problems[0].startswith("board.yaml:11:")
    assert "devices.acc.settings.odr_hz" in problems[0]
    assert "50 or 100" in problems[0] and "found 75" in problems[0]


def test_a_reflection_mount_is_named(registry: Registry) -> None:
    problems = _problems(GOOD.replace('"-Y-X-Z"', '"+Y+X+Z"'), registry)
    assert "board.yaml:10:12: devices.acc.mount" in problems[0]
    assert "reflection" in problems[0]


def test_every_problem_is_reported_at_once(registry: Registry) -> None:
    text = GOOD.replace("odr_hz: 100", "odr_hz: 75").replace("bus: i2c1", "bus: i2c9")
    text = text.replace("driver: tc3", "driver: tc3") + "estimators:\n  e: {estimator: nope}\n"
    problems = _problems(text, registry)
    joined = "\n".join(problems)
    assert "no bus named 'i2c9'" in joined
    assert "no estimator named 'nope'" in joined
    assert len(problems) >= 2


def test_an_unknown_driver_lists_the_installed_ones(registry: Registry) -> None:
    problems = _problems(GOOD.replace("driver: tc3", "driver: tc4"), registry)
    assert "devices.acc.driver: no driver named 'tc4' is installed" in problems[0]
    assert "tc3" in problems[0]


def test_a_missing_key_says_to_add_it(registry: Registry) -> None:
    problems = _problems(GOOD.replace("    address: 0x19\n", ""), registry)
    assert "devices.acc.address: required key is missing; add it" in problems[0]


def test_a_duplicate_key_is_an_error(registry: Registry) -> None:
    problems = _problems(GOOD.replace("    address: 0x19\n",
                                      "    address: 0x19\n    address: 0x18\n"), registry)
    assert any("duplicate key" in p and "devices.acc.address" in p for p in problems)


def test_yaml_syntax_errors_are_located(registry: Registry) -> None:
    problems = _problems("schema_version: 1\nname: [oops\n", registry)
    assert problems[0].startswith("board.yaml:") and "YAML syntax error" in problems[0]


def test_an_unsupported_schema_version_says_which_is_read(registry: Registry) -> None:
    problems = _problems(GOOD.replace("schema_version: 1", "schema_version: 7"), registry)
    assert "schema_version 1" in problems[0] and "7" in problems[0]


def test_a_bus_setting_is_checked_by_the_bus_plugin(registry: Registry) -> None:
    problems = _problems(GOOD.replace("{kind: i2c, device: /dev/i2c-1}",
                                      "{kind: i2c, device: /dev/i2c-1, speed: 400000}"), registry)
    assert "buses.i2c1.speed: unknown key" in problems[0]
    assert "allowed keys: device" in problems[0]


def test_a_driver_on_a_bus_kind_it_does_not_support_is_refused(registry: Registry) -> None:
    text = GOOD.replace("{kind: i2c, device: /dev/i2c-1}", "{kind: serial, port: /dev/ttyS0}")
    problems = _problems(text, registry)
    assert "cannot sit on a serial bus" in problems[0]


def test_a_missing_file_is_a_profile_error() -> None:
    with pytest.raises(ProfileError, match="file not found"):
        load_profile("does-not-exist.yaml")


def test_check_profile_returns_no_problems_for_a_good_file(
    registry: Registry, tmp_path: Path
) -> None:
    path = tmp_path / "good.yaml"
    path.write_text(GOOD)
    assert check_profile(path, registry) == []


def test_the_yaml_loader_refuses_python_object_tags(registry: Registry) -> None:
    problems = _problems(GOOD + "evil: !!python/object/apply:os.system ['true']\n", registry)
    assert "not allowed" in problems[0] and "python/object" in problems[0]


@pytest.mark.parametrize(("old", "new"), [("ros", "mcap"), ("mavlink", "mavlink"),
                                          ("igc", "igc")])
def test_a_top_level_output_section_of_old_is_one_error_naming_its_place_under_outputs(
        old: str, new: str) -> None:
    from imuhal.plugins.manager import load_registry

    text = (f"schema_version: 1\nname: old\nbuses:\n  spi0: {{kind: spi}}\ndevices:\n"
            f"  baro: {{driver: ms5611, bus: spi0, address: 0}}\n{old}: {{}}\n")
    with pytest.raises(ProfileError) as caught:
        parse_profile(text, "old.yaml", load_registry())
    assert str(caught.value).splitlines() == [
        f"old.yaml:7:1: {old}: moved under outputs: write `outputs: {{{new}: ...}}` with the "
        "same keys (docs/profiles.md)"]


def test_each_output_reads_its_section_under_outputs() -> None:
    from imuhal.plugins.manager import load_registry

    text = ("schema_version: 1\nname: new\nbuses:\n  spi0: {kind: spi}\ndevices:\n"
            "  baro: {driver: ms5611, bus: spi0, address: 0}\noutputs:\n"
            "  igc: {pilot: Jane Doe}\n  mcap: {frame_id: imu_link}\n"
            "  mavlink: {system_id: 7}\n  mqtt: {board: glider-7}\n")
    outputs = parse_profile(text, "new.yaml", load_registry()).outputs
    assert (outputs.igc.pilot, outputs.mcap.frame_id, outputs.mavlink.system_id) == (
        "Jane Doe", "imu_link", 7)
    assert outputs.plugin_sections() == {"mqtt": {"board": "glider-7"}}


def test_a_mistake_in_a_built_in_outputs_section_names_its_key() -> None:
    from imuhal.plugins.manager import load_registry

    text = ("schema_version: 1\nname: new\nbuses:\n  spi0: {kind: spi}\ndevices:\n"
            "  baro: {driver: ms5611, bus: spi0, address: 0}\noutputs:\n"
            "  mavlink: {system_id: 0}\n")
    with pytest.raises(ProfileError, match=r"outputs\.mavlink\.system_id"):
        parse_profile(text, "new.yaml", load_registry())
