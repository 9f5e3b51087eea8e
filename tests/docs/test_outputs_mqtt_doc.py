"""docs/outputs.md, "## MQTT": the profile section it shows loads, its settings table lists
exactly the sink's settings, and the summary counters it explains are the sink's."""

from __future__ import annotations

import re
from pathlib import Path

from imuhal.plugins.manager import load_registry
from imuhal.profile.bundled import bundled_profiles
from imuhal.profile.loader import parse_profile
from imuhal.sinks.mqtt import COUNTERS, MqttSettings

DOC = Path(__file__).resolve().parents[2] / "docs" / "outputs.md"


def _mqtt_section() -> str:
    text = DOC.read_text(encoding="utf-8")
    start = text.index("\n## MQTT\n")
    end = text.find("\n## ", start + 1)
    return text[start:] if end < 0 else text[start:end]


def test_the_profile_section_shown_loads_with_the_bundled_board() -> None:
    block = re.findall(r"```yaml\n(.*?)```", _mqtt_section(), re.S)
    assert len(block) == 1 and block[0].startswith("outputs:\n  mqtt:")
    board = bundled_profiles()["seed-gps-vario.yaml"].read_text(encoding="utf-8")
    profile = parse_profile(board + block[0], "seed-gps-vario.yaml + docs", load_registry())
    MqttSettings.model_validate(profile.outputs.plugin_sections()["mqtt"])


def test_the_settings_table_lists_every_setting_and_no_other() -> None:
    table = re.findall(r"^\| `([a-z_]+)` \|", _mqtt_section(), re.M)
    rows = table[table.index("url"):]
    assert rows == list(MqttSettings.model_fields)


def test_every_summary_counter_is_explained() -> None:
    section = _mqtt_section()
    for name in COUNTERS:
        assert f"`{name.replace('_', ' ')}`" in section, name
