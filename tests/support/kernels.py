"""Test fixtures for the compiled kernels: the AOT extension built once per session, and a
parameter that runs a test on each compiled backend (``IMUHAL_KERNELS``)."""

from __future__ import annotations

import importlib.util
import os
import shutil
import subprocess
import sys
import sysconfig
from collections.abc import Iterator
from pathlib import Path

import pytest
from filelock import FileLock


def cli_env(**extra: str) -> dict[str, str]:
    """The environment for a child ``imuhal`` process: this one's, without any kernel
    selection the developer has set, plus ``extra``."""
    env = {k: v for k, v in os.environ.items()
           if k not in ("IMUHAL_KERNELS", "IMUHAL_NO_JIT", "IMUHAL_KERNEL_DIR")}
    env.update(extra)
    return env


def why_no_build() -> str | None:
    """Why this machine cannot build the extension (None: it can, so a failure is a bug)."""
    if importlib.util.find_spec("numba") is None:
        return "numba not installed (pip install -e '.[fast]')"
    if importlib.util.find_spec("numba.pycc") is None:
        return "this numba has no numba.pycc"
    if not (Path(sysconfig.get_paths()["include"]) / "Python.h").is_file():
        return "no Python C headers (apt-get install python3-dev)"
    if shutil.which(os.environ.get("CC", "cc")) is None and shutil.which("gcc") is None:
        return "no C compiler (apt-get install gcc)"
    return None


@pytest.fixture(scope="session")
def aot_kernel_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A kernel directory with every kernel built by ``imuhal kernels build`` (once per
    session: about a minute of CPU for its 12 kernels, several at a loaded machine's pace);
    skipped with the reason where the tools are missing.

    Under pytest-xdist the workers share one build: the first to need it builds it in the
    session's common temporary folder while holding a file lock, the others wait on the lock
    and reuse it (a build per worker cost a minute of setup each). Tests copy the folder
    before they change anything in it."""
    why = why_no_build()
    if why is not None:
        pytest.skip(f"no AOT kernel extension can be built here: {why}")
    root = tmp_path_factory.getbasetemp()
    if os.environ.get("PYTEST_XDIST_WORKER"):
        root = root.parent  # the workers' basetemps are siblings in the session's folder
    d = root / "aot-kernels"
    # beside the folder, not in it: tests copy every file of the folder
    built = root / "aot-kernels.built"
    with FileLock(str(root / "aot-kernels.lock")):
        if not built.is_file():
            shutil.rmtree(d, ignore_errors=True)  # what a failed build of another worker left
            d.mkdir()
            done = subprocess.run(
                [sys.executable, "-m", "imuhal.cli.main", "kernels", "build"],
                env=cli_env(IMUHAL_KERNEL_DIR=str(d)), capture_output=True, text=True,
                timeout=900)
            assert done.returncode == 0, done.stderr
            built.touch()
    return d


@pytest.fixture(params=["jit", "aot"])
def compiled_backend(request: pytest.FixtureRequest, monkeypatch: pytest.MonkeyPatch
                     ) -> Iterator[str]:
    """Runs the test once with numba's JIT and once with the AOT extension, forced (a kernel
    the backend cannot run is an error, not a silent fallback); skipped where unavailable."""
    backend = request.param
    monkeypatch.delenv("IMUHAL_NO_JIT", raising=False)
    if backend == "jit":
        if importlib.util.find_spec("numba") is None:
            pytest.skip("numba not installed (pip install -e '.[fast]')")
    else:
        monkeypatch.setenv("IMUHAL_KERNEL_DIR", str(request.getfixturevalue("aot_kernel_dir")))
    monkeypatch.setenv("IMUHAL_KERNELS", backend)
    yield backend
