"""docs/writing-a-driver.md's example plugin runs as written: every code block headed by a
file name (``# acme3/driver.py``, ``# acme3-board.yaml``) is copied out of the page into a
temporary package, registered as a plugin like a third party's, and its board is flown on
the emulated bus against the simulator's truth."""

from __future__ import annotations

import importlib
import re
import sys
from collections.abc import Iterator
from pathlib import Path

import pytest

from imuhal.core.samples import AccelSample
from imuhal.emulation import EmulatedBoard, open_emulated
from imuhal.plugins.manager import load_registry
from imuhal.profile.loader import load_profile

ROOT = Path(__file__).resolve().parents[2]
PAGE = ROOT / "docs" / "writing-a-driver.md"
G = 9.80665
COUNT_M_S2 = 1e-3 * G  # the ACME3's 1 mg per count
RUN_S = 60.0
ODR_HZ = 100.0


def named_blocks(page: str) -> dict[str, str]:
    """The page's code blocks whose first line is a comment naming a file, by that name."""
    return {name: body for name, body in re.findall(
        r"```(?:python|yaml)\n# ([\w./-]+\.(?:py|yaml))\n(.*?)```", page, flags=re.S)}


@pytest.fixture
def acme3(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Iterator[Path]:
    """The page's files written out; the acme3 package importable from them."""
    for name, body in named_blocks(PAGE.read_text(encoding="utf-8")).items():
        target = tmp_path / name
        target.parent.mkdir(parents=True, exist_ok=True)
        target.write_text(body, encoding="utf-8")
    (tmp_path / "acme3" / "__init__.py").touch()
    monkeypatch.syspath_prepend(str(tmp_path))
    yield tmp_path
    for module in [m for m in sys.modules if m == "acme3" or m.startswith("acme3.")]:
        del sys.modules[module]


def test_the_page_holds_every_file_of_the_example() -> None:
    assert set(named_blocks(PAGE.read_text(encoding="utf-8"))) == {
        "acme3/registers.py", "acme3/driver.py", "acme3/emulator.py", "acme3/plugin.py",
        "acme3-board.yaml"}


def test_the_example_board_flies_against_the_simulators_truth(acme3: Path) -> None:
    plugin = importlib.import_module("acme3.plugin")
    registry = load_registry(extra=[("acme3", plugin)])
    profile = load_profile(acme3 / "acme3-board.yaml", registry)
    with open_emulated(profile, registry) as pipeline:
        scenario = EmulatedBoard.of(pipeline).scenario
        samples = [e for e in pipeline.events(duration_s=RUN_S) if isinstance(e, AccelSample)]
    assert len(samples) == pytest.approx(RUN_S * ODR_HZ, rel=0.02)
    assert all(s.valid for s in samples)
    # The board's mount is the identity: the chip reads the body's specific force. It reads
    # the measurement latched up to one output period before the poll, so only where the
    # hand holds the board still must it agree to within the rounding of one count.
    close = [s for s in samples if max(
        abs(a - t) for a, t in zip(s.accel_m_s2, scenario.chip_truth(
            s.t_ns / 1e9).specific_force_body_m_s2, strict=True)) <= 1.5 * COUNT_M_S2]
    assert len(close) >= 0.9 * len(samples)
    held = {(axis, 1 if s.accel_m_s2[axis] > 0 else -1) for s in close
            for axis in range(3) if abs(abs(s.accel_m_s2[axis]) - G) < 2 * COUNT_M_S2}
    assert held == {(axis, sign) for axis in range(3) for sign in (1, -1)}
