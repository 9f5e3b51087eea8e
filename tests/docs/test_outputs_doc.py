"""docs/outputs.md: its profile sections are what the profile schema accepts, and every
command-line flag it shows exists."""

from __future__ import annotations

import re
from pathlib import Path

import pytest
import yaml

from imuhal.cli.main import main
from imuhal.sinks.foxglove_live import FoxgloveSettings
from imuhal.sinks.mavlink.settings import MavlinkSettings
from imuhal.sinks.ros.settings import RosSettings

DOC = Path(__file__).resolve().parents[2] / "docs" / "outputs.md"


def _blocks(lang: str) -> list[str]:
    return re.findall(rf"```{lang}\n(.*?)```", DOC.read_text(encoding="utf-8"), re.S)


def test_the_mcap_mavlink_and_foxglove_sections_shown_are_valid_profile_sections() -> None:
    blocks = [yaml.safe_load(block) for block in _blocks("yaml")]
    assert all(set(b) == {"outputs"} for b in blocks)  # every output under outputs:
    sections = {k: v for b in blocks for k, v in b["outputs"].items()}
    assert set(sections) == {"mcap", "mavlink", "mqtt", "foxglove"}  # mqtt: its own test
    RosSettings.model_validate(sections["mcap"])
    MavlinkSettings.model_validate(sections["mavlink"])
    FoxgloveSettings.model_validate(sections["foxglove"])


def test_the_foxglove_settings_table_lists_every_setting_and_no_other() -> None:
    text = DOC.read_text(encoding="utf-8")
    section = text[text.index("\n## Foxglove (live)\n"):text.index("\n## MAVLink\n")]
    table = re.findall(r"^\| `([a-z_]+)` \|", section, re.M)
    assert table == list(FoxgloveSettings.model_fields)


@pytest.mark.parametrize("command", ["run", "replay", "estimate"])
def test_every_flag_the_page_shows_for_a_command_is_in_its_help(
        command: str, capsys: pytest.CaptureFixture[str]) -> None:
    text = " ".join(b.replace("\\\n", " ") for b in _blocks("sh"))
    flags = {f for line in re.findall(rf"imuhal {command} [^\n]*", text)
             for f in re.findall(r"--[a-z][a-z-]*", line)}
    assert flags
    with pytest.raises(SystemExit):
        main([command, "--help"])
    assert flags <= set(re.findall(r"--[a-z][a-z-]*", capsys.readouterr().out))
