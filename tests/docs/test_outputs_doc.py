"""docs/outputs.md: its profile sections are what the profile schema accepts, and every
command-line flag it shows exists."""

from __future__ import annotations

import re
from pathlib import Path

import pytest
import yaml

from imuhal.cli.main import main
from imuhal.sinks.mavlink.settings import MavlinkSettings
from imuhal.sinks.ros.settings import RosSettings

DOC = Path(__file__).resolve().parents[2] / "docs" / "outputs.md"


def _blocks(lang: str) -> list[str]:
    return re.findall(rf"```{lang}\n(.*?)```", DOC.read_text(encoding="utf-8"), re.S)


def test_the_mcap_and_mavlink_sections_shown_are_valid_profile_sections() -> None:
    blocks = [yaml.safe_load(block) for block in _blocks("yaml")]
    assert all(set(b) == {"outputs"} for b in blocks)  # every output under outputs:
    sections = {k: v for b in blocks for k, v in b["outputs"].items()}
    assert set(sections) == {"mcap", "mavlink", "mqtt"}  # mqtt: test_outputs_mqtt_doc
    RosSettings.model_validate(sections["mcap"])
    MavlinkSettings.model_validate(sections["mavlink"])


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
