"""A third-party plugin package, built and installed in a temporary directory, is found
through its entry points and works with no change to imuhal itself: its driver runs in a
profile, and it adds a physical quantity (relative humidity: its sample class, driver and
emulator), a sink and a command-line command, and a vector quantity imuhal calibrates
(tests/support/sensor_plugin.py)."""

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
acme_sensors = "acme_tc3.sensors"

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

HUMIDITY_PROFILE = """
schema_version: 1
name: acme-weather
buses:
  i2c1: {kind: i2c, device: /dev/i2c-1}
devices:
  hum:
    driver: hh1
    bus: i2c1
    address: 0x40
    settings: {odr_hz: 10}
emulation:
  scenario: static
"""

AIRFLOW_PROFILE = """
schema_version: 1
name: acme-flow
buses:
  i2c1: {kind: i2c, device: /dev/i2c-1}
devices:
  flow: {driver: af3, bus: i2c1, address: 0x28}
emulation: {scenario: static}
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
    shutil.copy(ROOT / "tests" / "support" / "sensor_plugin.py", pkg / "sensors.py")
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


@pytest.mark.slow
def test_the_plugin_quantity_sink_and_command_are_listed(installed_plugin: Path) -> None:
    out = _imuhal(installed_plugin, "plugins")
    assert out.returncode == 0, out.stderr
    lines = {li.split()[0]: li for li in out.stdout.splitlines() if li.startswith("  ")}
    assert "scalar, %RH" in lines["humidity"]
    assert "imuhal-acme-tc3:acme_sensors" in lines["humidity-log"]
    assert "imuhal-acme-tc3:acme_sensors" in lines["humidity-stats"]


@pytest.mark.slow
def test_a_plugin_quantity_flows_from_its_scenario_through_the_pipeline_into_its_sink(
        installed_plugin: Path, tmp_path: Path) -> None:
    profile = tmp_path / "weather.yaml"
    profile.write_text(textwrap.dedent(HUMIDITY_PROFILE))
    log = tmp_path / "humidity.csv"
    result = _imuhal(installed_plugin, "run", str(profile), "--emulate", "humid-static",
                     "--duration", "2", "--sink", "humidity-log",
                     "--sink-set", f"humidity-log.path={log}", "--quiet")
    assert result.returncode == 0, result.stderr
    assert "hum: 20 samples" in result.stderr  # 10 Hz x 2 s, none flagged
    rows = [r.split(",") for r in log.read_text().splitlines()[1:]]
    assert len(rows) == 20
    # The plugin's world: 40 %RH + 10 %RH/s, read back within one 16-bit count (0.0015 %RH).
    assert all(abs(float(rh) - (40.0 + 10.0 * float(t))) < 0.002 for t, _, rh in rows)


@pytest.mark.slow
def test_a_plugin_command_runs_with_the_registry(installed_plugin: Path, tmp_path: Path) -> None:
    log = tmp_path / "humidity.csv"
    log.write_text("t_s,device,humidity_pct\n0.0,hum,40.0\n0.1,hum,42.0\n")
    out = _imuhal(installed_plugin, "humidity-stats", str(log))
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "2 samples, mean 41.00 %RH"


@pytest.mark.slow
def test_a_plugin_command_error_is_one_line_and_exit_2(installed_plugin: Path,
                                                       tmp_path: Path) -> None:
    out = _imuhal(installed_plugin, "humidity-stats", str(tmp_path / "none.csv"))
    assert out.returncode == 2
    assert out.stderr.count("\n") == 1 and "no such humidity log" in out.stderr


@pytest.mark.slow
def test_an_unknown_sink_setting_is_a_one_line_error_naming_it(
        installed_plugin: Path, tmp_path: Path) -> None:
    profile = tmp_path / "weather.yaml"
    profile.write_text(textwrap.dedent(HUMIDITY_PROFILE))
    out = _imuhal(installed_plugin, "run", str(profile), "--emulate", "static",
                  "--duration", "1", "--sink", "humidity-log",
                  "--sink-set", "humidity-log.colour=red", "--quiet")
    assert out.returncode == 2
    assert "--sink-set humidity-log.colour: sink 'humidity-log' has no such setting" \
        in out.stderr


@pytest.mark.slow
def test_the_plugin_vector_quantity_is_calibrated_and_stored_by_imuhal_calibrate(
        installed_plugin: Path, tmp_path: Path) -> None:
    profile = tmp_path / "flow.yaml"
    profile.write_text(textwrap.dedent(AIRFLOW_PROFILE))
    out = _imuhal(installed_plugin, "calibrate", "vector-zero", str(profile), "--quantity",
                  "airflow", "--emulate", "static", "--set", "samples=20")
    assert out.returncode == 0, out.stderr
    assert "wrote devices.flow.calibration.airflow" in out.stderr
    shown = _imuhal(installed_plugin, "calibrate", "--show", str(profile))
    assert shown.returncode == 0, shown.stderr
    # The emulated AF3 reads (0.5, -0.25, 0.125) m/s in still air.
    assert "airflow: vector-zero" in shown.stdout
    assert "offset: (+0.5, -0.25, +0.125)" in shown.stdout
