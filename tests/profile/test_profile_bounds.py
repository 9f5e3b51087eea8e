"""Bounded, strict profiles: hostile files fail fast with a clear error, values have the type
and range they claim, and every problem (structure, addresses, calibration, plugin settings,
schema version) is in one report."""

from __future__ import annotations

import signal
import textwrap
from pathlib import Path

import pytest

from imuhal.core.errors import ProfileError
from imuhal.plugins.manager import Registry, load_registry
from imuhal.profile.bundled import default_profile_path
from imuhal.profile.loader import MAX_PROFILE_BYTES, check_profile, parse_profile

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
    settings: {odr_hz: 100}
"""

BILLION_LAUGHS = """\
a: &a ["lol","lol","lol","lol","lol","lol","lol","lol","lol"]
b: &b [*a,*a,*a,*a,*a,*a,*a,*a,*a]
c: &c [*b,*b,*b,*b,*b,*b,*b,*b,*b]
d: &d [*c,*c,*c,*c,*c,*c,*c,*c,*c]
e: &e [*d,*d,*d,*d,*d,*d,*d,*d,*d]
f: &f [*e,*e,*e,*e,*e,*e,*e,*e,*e]
g: &g [*f,*f,*f,*f,*f,*f,*f,*f,*f]
h: &h [*g,*g,*g,*g,*g,*g,*g,*g,*g]
i: &i [*h,*h,*h,*h,*h,*h,*h,*h,*h]
"""


def _problems(text: str, registry: Registry) -> list[str]:
    with pytest.raises(ProfileError) as info:
        parse_profile(textwrap.dedent(text), "board.yaml", registry)
    return info.value.problems


def _hang(signum: int, frame: object) -> None:
    raise AssertionError("the alias bomb was expanded (still running after 5 s)")


def test_an_alias_bomb_is_refused_before_it_expands(registry: Registry) -> None:
    """Issue 9 item 15."""
    assert len(BILLION_LAUGHS.encode()) < 400  # 9**9 values once expanded
    # A hang guard, not a speed test: refusing takes about 2 ms, expanding would take minutes
    # and gigabytes (docs/profiles.md).
    previous = signal.signal(signal.SIGALRM, _hang)
    signal.alarm(5)
    try:
        problems = _problems(BILLION_LAUGHS, registry)
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, previous)
    assert len(problems) == 1
    assert "expands to more than" in problems[0] and "aliases" in problems[0]
    assert problems[0].startswith("board.yaml:")


def test_a_recursive_alias_is_refused(registry: Registry) -> None:
    problems = _problems("a: &a [1, *a]\n", registry)
    assert "recursive alias" in problems[0]


def test_aliases_of_a_real_profile_size_are_fine(registry: Registry) -> None:
    text = GOOD.replace("settings: {odr_hz: 100}", "settings: &s {odr_hz: 100}")
    assert parse_profile(text, "board.yaml", registry).devices["acc"].settings == {"odr_hz": 100}


def test_a_file_larger_than_the_cap_is_refused_unread(tmp_path: Path,
                                                      registry: Registry) -> None:
    """Issue 9 item 15."""
    big = tmp_path / "big.yaml"
    big.write_text(GOOD + "#" * MAX_PROFILE_BYTES + "\n")
    problems = check_profile(big, registry)
    assert len(problems) == 1 and "larger than 1 MB" in problems[0]


@pytest.fixture(scope="module")
def installed() -> Registry:
    return load_registry()


@pytest.mark.parametrize("value", ["true", '"100"', "[100]"])
def test_a_number_setting_takes_no_bool_and_no_string(value: str,
                                                               registry: Registry) -> None:
    problems = _problems(GOOD.replace("odr_hz: 100", f"odr_hz: {value}"), registry)
    assert len(problems) == 1 and "devices.acc.settings.odr_hz" in problems[0]


def test_a_bool_is_not_a_rate_in_a_bundled_board(installed: Registry) -> None:
    """Issue 9 item 16."""
    text = default_profile_path().read_text().replace("odr_hz: 50", "odr_hz: true")
    problems = _problems(text, installed)
    assert len(problems) == 1
    assert "devices.baro.settings.odr_hz" in problems[0] and "True" in problems[0]


def test_a_bool_is_not_an_address(registry: Registry) -> None:
    problems = _problems(GOOD.replace("address: 0x19", "address: true"), registry)
    assert "board.yaml:9:14: devices.acc.address" in problems[0]


def test_two_devices_at_one_address_are_located(registry: Registry) -> None:
    """Issue 9 item 16."""
    text = GOOD + "  acc2:\n    driver: tc3\n    bus: i2c1\n    address: 0x19\n"
    problems = _problems(text, registry)
    assert len(problems) == 1
    assert problems[0].startswith("board.yaml:14:14: devices.acc2.address: 0x19 on bus 'i2c1' "
                                  "is already taken by devices.acc (board.yaml:9:14)")


def test_a_disabled_device_may_share_an_address(registry: Registry) -> None:
    text = GOOD + "  acc2:\n    driver: tc3\n    bus: i2c1\n    address: 0x19\n    enabled: false\n"
    assert set(parse_profile(text, "board.yaml", registry).devices) == {"acc", "acc2"}


@pytest.mark.parametrize(("record", "field"), [
    ("gyro: {offset_rad_s: [.nan, 0, 0]}", "gyro.offset_rad_s"),
    ("gyro: {scale: [1, 0, 1]}", "gyro.scale"),
    ("accel: {offset_m_s2: [0, .inf, 0]}", "accel.offset_m_s2"),
    ("accel: {scale: [1, 1, 0.0]}", "accel.scale"),
    ("accel: {scale: [1, -1, 1]}", "accel.scale"),
    ("mag: {hard_iron_ut: [0, 0, -.inf]}", "mag.hard_iron_ut"),
    ("mag: {soft_iron: [[1, 0, 0], [0, 0, 0], [0, 0, 1]]}", "mag.soft_iron"),
])
def test_a_degenerate_calibration_value_is_a_located_error(record: str, field: str,
                                                            registry: Registry) -> None:
    """Issue 9 item 9."""
    text = GOOD + f"    calibration:\n      {record}\n"
    # (The test chip has no gyro or magnetometer, which is a second, separate problem for
    # the gyro and mag records: only the located value error is checked here.)
    problems = [p for p in _problems(text, registry) if "measures no vector quantity" not in p]
    assert len(problems) == 1
    assert problems[0].startswith("board.yaml:12:")
    assert f"devices.acc.calibration.{field}" in problems[0]


def test_a_wrong_schema_version_does_not_hide_other_problems(registry: Registry) -> None:
    """Issue 9 item 16."""
    text = GOOD.replace("schema_version: 1", "schema_version: 2").replace("bus: i2c1", "bus: x")
    joined = "\n".join(_problems(text, registry))
    assert "schema_version: 2 is not supported" in joined
    assert "no bus named 'x'" in joined


def test_a_bool_schema_version_is_not_version_1(registry: Registry) -> None:
    problems = _problems(GOOD.replace("schema_version: 1", "schema_version: true"), registry)
    assert "schema_version: True is not supported" in problems[0]


def test_settings_errors_come_in_the_same_report_as_structural_ones(installed: Registry) -> None:
    """Issue 9 item 16."""
    text = default_profile_path().read_text().replace("name: seed-paraglider-vario\n", "")
    text = text.replace("odr_hz: 75", "odr_hz: 76").replace("nominal_airspeed_m_s: 10",
                                                               "nominal_airspeed_m_s: yes")
    joined = "\n".join(_problems(text, installed))
    assert "name: required key is missing" in joined
    assert "devices.mag.settings.odr_hz" in joined
    assert "estimators.ahrs.settings.nominal_airspeed_m_s" in joined


@pytest.mark.parametrize("value", ["true", '"500"'])
def test_a_table_setting_takes_only_numbers(value: str, installed: Registry) -> None:
    text = default_profile_path().read_text().replace("gyro_range_dps: 500",
                                                      f"gyro_range_dps: {value}")
    problems = _problems(text, installed)
    assert len(problems) == 1
    assert "devices.imu.settings.gyro_range_dps" in problems[0]
    assert "must be a number in dps; allowed: 250, 500" in problems[0]
