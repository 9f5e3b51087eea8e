"""A third-party plugin package, built and installed in a temporary directory, is found
through its entry point and its driver runs, with no change to imuhal itself."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]

PYPROJECT = """
[build-system]
requires = ["setuptools>=61"]
build-backend = "setuptools.build_meta"

[project]
name = "imuhal-acme-tc3"
version = "1.0"

[project.entry-points.imuhal]
acme_tc3 = "acme_tc3.plugin"

[tool.setuptools]
packages = ["acme_tc3"]
"""

PROFILE = """
schema_version: 1
name: acme-board
buses:
  i2c1: {kind: i2c, device: /dev/i2c-1}
devices:
  acc:
    driver: tc3
    bus: i2c1
    address: 0x19
    settings: {odr_hz: 100}
emulation:
  scenario: thermal
"""


@pytest.fixture(scope="module")
def installed_plugin(tmp_path_factory: pytest.TempPathFactory) -> Path:
    src = tmp_path_factory.mktemp("acme-src")
    (src / "pyproject.toml").write_text(PYPROJECT)
    pkg = src / "acme_tc3"
    pkg.mkdir()
    (pkg / "__init__.py").write_text("")
    # The plugin's code is the test chip module: a driver and emulator that core never saw.
    shutil.copy(ROOT / "tests" / "support" / "testchip.py", pkg / "plugin.py")
    target = tmp_path_factory.mktemp("acme-site")
    subprocess.run(
        [sys.executable, "-m", "pip", "install", "--quiet", "--no-deps", "--no-build-isolation",
         "--target", str(target), str(src)],
        check=True, capture_output=True, text=True,
    )
    return target


def _imuhal(target: Path, *args: str) -> subprocess.CompletedProcess[str]:
    env = dict(os.environ, PYTHONPATH=str(target))
    return subprocess.run([sys.executable, "-m", "imuhal.cli.main", *args],
                          capture_output=True, text=True, env=env, timeout=120)


@pytest.mark.slow
def test_the_installed_plugin_is_listed_with_its_package(installed_plugin: Path) -> None:
    out = _imuhal(installed_plugin, "plugins")
    assert out.returncode == 0, out.stderr
    line = next(li for li in out.stdout.splitlines() if li.strip().startswith("tc3"))
    assert "imuhal-acme-tc3:acme_tc3" in line


@pytest.mark.slow
def test_the_installed_plugin_runs_in_a_profile(installed_plugin: Path, tmp_path: Path) -> None:
    profile = tmp_path / "acme.yaml"
    profile.write_text(textwrap.dedent(PROFILE))
    out_csv = tmp_path / "out.csv"
    result = _imuhal(installed_plugin, "run", str(profile), "--emulate", "thermal",
                     "--duration", "2", "--output", str(out_csv), "--samples", "--quiet")
    assert result.returncode == 0, result.stderr
    assert "acc: 400 samples" in result.stderr  # 100 Hz x 2 s x (accel + pressure)
    assert out_csv.read_text().count("\n") > 400
