"""``imuhal kernels build|status`` and the kernel backend settings, as a user meets them: each
mistake or missing tool is one line on stderr naming the fix (exit 2), and a failed build
leaves the kernel directory as it was."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from tests.support.kernels import cli_env, why_no_build

from imuhal.cli import main as cli_main


def _one_line_error(capsys: pytest.CaptureFixture[str], code: int | str | None) -> str:
    err = capsys.readouterr().err
    lines = err.strip().splitlines()
    assert code == 2, err
    assert "Traceback" not in err and "internal error" not in err
    assert len(lines) == 1, err
    return lines[0]


@pytest.fixture
def no_kernel_env(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> Path:
    """An empty kernel directory, no backend forced."""
    d = tmp_path / "kernels"
    monkeypatch.setenv("IMUHAL_KERNEL_DIR", str(d))
    monkeypatch.delenv("IMUHAL_NO_JIT", raising=False)
    monkeypatch.delenv("IMUHAL_KERNELS", raising=False)
    return d


def test_build_without_numba_names_the_fast_extra(
        no_kernel_env: Path, monkeypatch: pytest.MonkeyPatch,
        capsys: pytest.CaptureFixture[str]) -> None:
    monkeypatch.setitem(sys.modules, "numba", None)  # what `import numba` meets without it
    line = _one_line_error(capsys, cli_main.main(["kernels", "build"]))
    assert "needs numba" in line and "pip install -e '.[fast]'" in line
    assert not no_kernel_env.exists()


def test_build_with_a_numba_that_lost_pycc_says_so(
        no_kernel_env: Path, monkeypatch: pytest.MonkeyPatch,
        capsys: pytest.CaptureFixture[str]) -> None:
    pytest.importorskip("numba", reason="numba not installed")
    monkeypatch.setitem(sys.modules, "numba.pycc", None)
    line = _one_line_error(capsys, cli_main.main(["kernels", "build"]))
    assert "has no numba.pycc" in line and "JIT" in line


def test_build_without_a_c_compiler_names_one(
        no_kernel_env: Path, capsys: pytest.CaptureFixture[str]) -> None:
    why = why_no_build()
    if why is not None and "C compiler" not in why:
        pytest.skip(f"the build stops earlier here: {why}")
    done = subprocess.run([sys.executable, "-m", "imuhal.cli.main", "kernels", "build"],
                          env=cli_env(IMUHAL_KERNEL_DIR=str(no_kernel_env),
                                      CC="/nonexistent/cc"),
                          capture_output=True, text=True, timeout=120)
    assert done.returncode == 2, done.stderr
    assert done.stderr.strip().count("\n") == 0
    assert "needs a working C compiler" in done.stderr and "gcc" in done.stderr
    assert not list(no_kernel_env.glob("imuhal_kernels_*"))


def test_build_into_a_kernel_directory_that_is_a_file_names_the_setting(
        no_kernel_env: Path, monkeypatch: pytest.MonkeyPatch,
        capsys: pytest.CaptureFixture[str]) -> None:
    why = why_no_build()
    if why is not None:
        pytest.skip(f"the build stops at its tools here: {why}")
    no_kernel_env.write_text("not a directory")
    line = _one_line_error(capsys, cli_main.main(["kernels", "build"]))
    assert "IMUHAL_KERNEL_DIR" in line and str(no_kernel_env) in line


def test_a_failed_build_keeps_the_good_extension(
        aot_kernel_dir: Path, tmp_path: Path) -> None:
    """The link fails (LDSHARED is a command that fails) after the compile: what was built
    before stays, byte for byte, and nothing half-built is left."""
    d = tmp_path / "kernels"
    d.mkdir()
    for f in aot_kernel_dir.iterdir():
        (d / f.name).write_bytes(f.read_bytes())
    before = {f.name: f.read_bytes() for f in d.iterdir()}
    # the timeout only guards against a hang: the build took 406 s once at load 10
    done = subprocess.run([sys.executable, "-m", "imuhal.cli.main", "kernels", "build"],
                          env=cli_env(IMUHAL_KERNEL_DIR=str(d), LDSHARED="false"),
                          capture_output=True, text=True, timeout=900)
    assert done.returncode == 2, done.stderr
    assert done.stderr.startswith("imuhal: error: building the kernel extension failed")
    assert "nothing was replaced" in done.stderr
    assert {f.name: f.read_bytes() for f in d.iterdir()} == before


def test_status_with_a_mistaken_backend_name_is_one_line(
        no_kernel_env: Path, monkeypatch: pytest.MonkeyPatch,
        capsys: pytest.CaptureFixture[str]) -> None:
    monkeypatch.setenv("IMUHAL_KERNELS", "fastest")
    line = _one_line_error(capsys, cli_main.main(["kernels", "status"]))
    assert "IMUHAL_KERNELS='fastest'" in line and "aot, jit, python" in line


def test_status_explains_a_missing_build(
        no_kernel_env: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert cli_main.main(["kernels", "status"]) == 0
    out = capsys.readouterr().out
    assert f"kernel directory: {no_kernel_env}" in out
    # seven batch kernels, Madgwick's and decoupled's block steps and four per-sample steps
    # said once per kernel, with the fix
    assert out.count(f"no extension built in {no_kernel_env} (run `imuhal kernels build`)") == 13
    assert out.count("no extension") == 13


def test_status_shows_per_sample_steps_on_python_without_an_extension(
        no_kernel_env: Path, capsys: pytest.CaptureFixture[str]) -> None:
    # numba's JIT is not used per sample in auto mode: status says what process() runs
    assert cli_main.main(["kernels", "status"]) == 0
    lines = [line.split() for line in capsys.readouterr().out.splitlines()]
    steps = {words[0]: words[1] for words in lines if words and words[0].endswith("_sample")}
    assert steps == {"madgwick_sample": "python", "mahony_sample": "python",
                     "imufilter_sample": "python", "decoupled_sample": "python"}


def test_estimate_forced_to_a_missing_extension_names_the_build(
        no_kernel_env: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
        capsys: pytest.CaptureFixture[str]) -> None:
    log = tmp_path / "imu.csv"
    rows = [f"{i * 0.004:.3f},0,0,0,0,0,-9.81" for i in range(300)]
    log.write_text("t_s,gx_rad_s,gy_rad_s,gz_rad_s,ax_m_s2,ay_m_s2,az_m_s2\n"
                   + "\n".join(rows) + "\n")
    monkeypatch.setenv("IMUHAL_KERNELS", "aot")
    out = tmp_path / "out.csv"
    line = _one_line_error(capsys, cli_main.main(["estimate", "madgwick", str(log), "-o",
                                                  str(out)]))
    assert "IMUHAL_KERNELS=aot" in line and "imuhal kernels build" in line
    assert not out.exists()
    assert np.loadtxt(log, delimiter=",", skiprows=1).shape == (300, 7)  # input untouched
