"""The kernel-test runner's host side (tests/kernel/run.py), without building or booting."""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path
from types import ModuleType

import pytest

RUNNER = Path(__file__).resolve().parents[1] / "kernel" / "run.py"


@pytest.fixture
def run() -> ModuleType:
    spec = importlib.util.spec_from_file_location("kernel_run", RUNNER)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_the_cache_entry_is_named_by_the_config_fragments_hash(run: ModuleType,
                                                               tmp_path: Path) -> None:
    fragment = tmp_path / "kernel.config"
    fragment.write_text("CONFIG_GPIO_SIM=y\n")
    run.FRAGMENT = fragment
    first = run.fragment_hash()
    fragment.write_text("CONFIG_GPIO_SIM=y\nCONFIG_BT=y\n")
    assert run.fragment_hash() != first and len(first) == 16


def test_the_cache_lives_in_the_users_cache_folder(run: ModuleType,
                                                   monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("XDG_CACHE_HOME", "/somewhere/cache")
    assert run.cache_root() == Path("/somewhere/cache/imuhal/kernel")
    monkeypatch.delenv("XDG_CACHE_HOME")
    assert run.cache_root() == Path.home() / ".cache" / "imuhal" / "kernel"


def test_a_missing_build_tool_is_one_line_naming_the_package(
        run: ModuleType, monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    monkeypatch.setenv("PATH", str(tmp_path))  # nothing to be found
    with pytest.raises(run.SetupError, match=r"^'make' not found .*apt-get install make$"):
        run.check_build_tools()


def test_a_missing_qemu_is_an_exit_2_before_anything_is_built(
        run: ModuleType, monkeypatch: pytest.MonkeyPatch, tmp_path: Path,
        capsys: pytest.CaptureFixture[str]) -> None:
    monkeypatch.setenv("PATH", str(tmp_path))
    monkeypatch.setattr(sys, "executable", str(tmp_path / "python"))  # no venv tools beside
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "cache"))
    assert run.main([]) == run.EXIT_USAGE
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "pip install -e \".[kernel]\"" in err
    assert not (tmp_path / "cache").exists()


def test_the_guest_runs_pytest_on_tests_kernel_with_the_guest_markers(
        run: ModuleType) -> None:
    line = run.guest_command(Path("/cache/modules/abc"), [])
    assert "IMUHAL_KERNEL_GUEST=1" in line and "IMUHAL_KERNEL_MODULES=/cache/modules/abc" in line
    assert line.endswith("-m pytest -p no:cacheprovider tests/kernel")
    assert run.guest_command(Path("/m"), ["-k", "gpio and not slow"]).endswith(
        "-k 'gpio and not slow' tests/kernel")
    assert run.guest_command(Path("/m"), ["tests/kernel/test_i2c.py", "-x"]).endswith(
        "tests/kernel/test_i2c.py -x")
