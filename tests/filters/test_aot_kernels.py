"""The ahead-of-time compiled kernels (``imuhal kernels build``): what runs from them and when.

An extension is used only while its fingerprint matches: a kernel whose source changed after
the build runs on the JIT (the other kernels keep the extension), never stale compiled code.
``imuhal estimate`` with the extension imports no numba. A forced backend that cannot run is a
one-line error. The equality of the compiled and Python results is proven, for the AOT
backend too, by tests/filters/test_compiled_*.py and test_rows_path.py.
"""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from tests.support.kernels import cli_env

import imuhal_filters
from imuhal.offline.csv_input import ACCEL, GYRO, MAG, TIME
from imuhal_filters.common import fast
from imuhal_filters.common.aot_build import exported_kernels
from imuhal_filters.imufilter.fast import to_global as imufilter_to_global
from imuhal_filters.madgwick.fast import madgwick_rows

PLUGINS = Path(imuhal_filters.__file__).resolve().parent


def _child(code: str, env: dict[str, str], *args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-c", code, *args], env=env, capture_output=True,
                          text=True, timeout=120)


def _status(env: dict[str, str]) -> dict[str, tuple[str, str]]:
    done = _child("from imuhal.cli.main import main; raise SystemExit(main())", env,
                  "kernels", "status")
    assert done.returncode == 0, done.stderr
    lines = [li.split(None, 2) for li in done.stdout.splitlines() if li.startswith("  ")]
    return {name: (backend, reason) for name, backend, reason in lines}


def _imu_csv(path: Path, n: int = 2000) -> Path:
    rng = np.random.default_rng(3)
    t = np.arange(n) * 0.004
    gyro = rng.normal(0.0, 0.05, (n, 3))
    accel = np.array([0.0, 0.0, -9.80665]) + rng.normal(0.0, 0.1, (n, 3))
    mag = np.array([20.0, 1.0, 44.0]) + rng.normal(0.0, 0.5, (n, 3))
    header = ",".join((TIME, *GYRO, *ACCEL, *MAG))
    np.savetxt(path, np.column_stack([t, gyro, accel, mag]), delimiter=",", header=header,
               comments="", fmt="%.9g")
    return path


def test_every_kernel_runs_from_a_fresh_build(aot_kernel_dir: Path) -> None:
    status = _status(cli_env(IMUHAL_KERNEL_DIR=str(aot_kernel_dir)))
    assert set(status) == {k.name for k in exported_kernels()}
    assert {backend for backend, _ in status.values()} == {"aot"}


def test_a_kernel_edited_after_the_build_falls_back_and_the_others_keep_the_extension(
        aot_kernel_dir: Path, tmp_path: Path) -> None:
    """A copy of the filters with one comment added to madgwick/fast.py (imported first
    through PYTHONPATH): its kernel runs on the JIT, not the extension's stale code."""
    pytest.importorskip("numba", reason="the fallback checked here is numba's JIT")
    copy = tmp_path / "src" / "imuhal_filters"
    shutil.copytree(PLUGINS, copy, ignore=shutil.ignore_patterns("__pycache__"))
    with (copy / "madgwick" / "fast.py").open("a") as f:
        f.write("# edited after the build\n")
    env = cli_env(IMUHAL_KERNEL_DIR=str(aot_kernel_dir), PYTHONPATH=str(tmp_path / "src"))
    status = _status(env)
    assert status["madgwick_rows"][0] == "jit"
    assert "stale: built for other sources" in status["madgwick_rows"][1]
    assert "madgwick/fast.py" in status["madgwick_rows"][1]
    assert status["mahony_rows"][0] == "aot"
    code = """
import sys, numpy as np
import imuhal_filters
from imuhal_filters.common.batch import run_batch
from imuhal_filters.madgwick.estimator import MadgwickEstimator
from imuhal_filters.madgwick.fast import madgwick_rows
n = 300
g = np.zeros((n, 3)); a = np.tile([0.0, 0.0, -9.8], (n, 1)); m = np.tile([20.0, 0, 40], (n, 1))
q = run_batch(MadgwickEstimator(), g, a, m, np.full(n, 0.004))
print(imuhal_filters.__file__, madgwick_rows.backend(), "numba" in sys.modules,
      bool(np.isfinite(q[-1]).all()))
"""
    done = _child(code, env)
    assert done.returncode == 0, done.stderr
    origin, backend, numba_loaded, finite = done.stdout.split()
    assert origin.startswith(str(copy))  # the edited copy ran
    assert (backend, numba_loaded, finite) == ("jit", "True", "True")


def test_a_shared_helper_edited_after_the_build_makes_every_kernel_calling_it_stale(
        aot_kernel_dir: Path, tmp_path: Path) -> None:
    """A copy of the filters with one comment added to common/fast_ahrs.py (the gate and
    row loop every AHRS kernel calls): each of those kernels falls back, the rest keep the
    extension."""
    copy = tmp_path / "src" / "imuhal_filters"
    shutil.copytree(PLUGINS, copy, ignore=shutil.ignore_patterns("__pycache__"))
    with (copy / "common" / "fast_ahrs.py").open("a") as f:
        f.write("# edited after the build\n")
    status = _status(cli_env(IMUHAL_KERNEL_DIR=str(aot_kernel_dir),
                             PYTHONPATH=str(tmp_path / "src")))
    callers = {"madgwick_rows", "madgwick_sample", "madgwick_block", "mahony_rows",
               "mahony_sample", "freescale_rows", "imufilter_rows"}
    for name in callers:
        backend, reason = status[name]
        assert backend != "aot", name
        assert "stale: built for other sources (imuhal_filters/common/fast_ahrs.py" in reason
    assert {name for name, (backend, _) in status.items() if backend == "aot"} == \
        set(status) - callers


def test_imuhal_estimate_with_the_extension_imports_no_numba(
        aot_kernel_dir: Path, tmp_path: Path) -> None:
    log = _imu_csv(tmp_path / "imu.csv")
    code = """
import json, sys
from imuhal.cli.main import main
rc = main(sys.argv[1:])
loaded = sorted(m for m in ("numba", "llvmlite") if m in sys.modules)
print(json.dumps({"rc": rc, "loaded": loaded}))
"""
    done = _child(code, cli_env(IMUHAL_KERNEL_DIR=str(aot_kernel_dir), IMUHAL_KERNELS="aot"),
                  "estimate", "madgwick", str(log), "-o", str(tmp_path / "out.csv"))
    assert json.loads(done.stdout.splitlines()[-1]) == {"rc": 0, "loaded": []}, done.stderr
    ref = _child(code, cli_env(IMUHAL_KERNELS="python"), "estimate", "madgwick", str(log),
                 "-o", str(tmp_path / "ref.csv"))
    assert json.loads(ref.stdout.splitlines()[-1])["rc"] == 0, ref.stderr
    out = np.genfromtxt(tmp_path / "out.csv", delimiter=",", names=True)
    expected = np.genfromtxt(tmp_path / "ref.csv", delimiter=",", names=True)
    assert out.dtype.names == expected.dtype.names
    assert len(out) == len(expected) == 2000
    for name in ("qw", "qx", "qy", "qz"):
        assert np.allclose(out[name], expected[name], rtol=0, atol=1e-12), name


def test_a_manifest_not_matching_its_file_name_is_ignored(
        aot_kernel_dir: Path, tmp_path: Path) -> None:
    """A manifest edited by hand (or half-copied) cannot vouch for an extension."""
    for f in aot_kernel_dir.iterdir():
        shutil.copy(f, tmp_path / f.name)
    manifest = next(tmp_path.glob("imuhal_kernels_*.json"))
    record = json.loads(manifest.read_text())
    record["sources"]["imuhal_filters.madgwick.fast"] = "0" * 64
    manifest.write_text(json.dumps(record))
    status = _status(cli_env(IMUHAL_KERNEL_DIR=str(tmp_path), IMUHAL_KERNELS="auto"))
    assert all(backend != "aot" for backend, _ in status.values())
    assert "no extension built" in status["mahony_rows"][1]


def _uses_a_helper_of_another_module(x):  # type: ignore[no-untyped-def]
    return imufilter_to_global(1.0, 0.0, 0.0, 0.0, x, 0.0, 0.0)


def test_a_kernel_fingerprint_covers_the_modules_of_the_helpers_it_calls() -> None:
    """A helper edited in another file makes the caller's extension stale too."""
    kernel = fast.Kernel(_uses_a_helper_of_another_module)
    assert kernel.modules() == [__name__, "imuhal_filters.imufilter.fast"]


def _enclosing_a_helper_of_another_module() -> fast.Kernel:
    helper = imufilter_to_global

    def _uses(x):  # type: ignore[no-untyped-def]
        return helper(1.0, 0.0, 0.0, 0.0, x, 0.0, 0.0)

    return fast.Kernel(_uses)


def test_a_kernel_fingerprint_covers_helpers_it_holds_as_closure_variables() -> None:
    """The shared row loop is made per filter around its step (common/fast_ahrs.py)."""
    assert _enclosing_a_helper_of_another_module().modules() == [
        __name__, "imuhal_filters.imufilter.fast"]
    assert set(madgwick_rows.modules()) == {"imuhal_filters.madgwick.fast",
                                            "imuhal_filters.common.fast_ahrs"}


def test_a_damaged_extension_falls_back_and_says_why(
        aot_kernel_dir: Path, tmp_path: Path) -> None:
    for f in aot_kernel_dir.iterdir():
        shutil.copy(f, tmp_path / f.name)
    extension = next(tmp_path.glob("imuhal_kernels_*.so"))
    extension.write_bytes(extension.read_bytes()[:4096])  # a copy cut short
    status = _status(cli_env(IMUHAL_KERNEL_DIR=str(tmp_path)))
    backend, reason = status["madgwick_rows"]
    assert backend != "aot"
    assert f"damaged: {extension.name}" in reason
