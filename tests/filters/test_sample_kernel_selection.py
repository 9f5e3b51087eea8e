"""Which backend runs the per-sample step (``Kernel.per_sample``).

A per-sample call is worth compiling only without numba's dispatcher in front: in ``auto``
mode the step runs compiled on the AOT extension alone, and numba's JIT runs it only when
``IMUHAL_KERNELS=jit`` forces it (tests, benchmarks).
"""

from __future__ import annotations

from pathlib import Path

import pytest

from imuhal_filters.madgwick.estimator import MadgwickEstimator


def _kernel(monkeypatch: pytest.MonkeyPatch, mode: str, kernel_dir: Path) -> object:
    monkeypatch.delenv("IMUHAL_NO_JIT", raising=False)
    monkeypatch.setenv("IMUHAL_KERNELS", mode)
    monkeypatch.setenv("IMUHAL_KERNEL_DIR", str(kernel_dir))
    return MadgwickEstimator(MadgwickEstimator.Settings())._sample_kernel


def test_auto_mode_without_an_extension_runs_the_python_step(
        monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    # even with numba installed: its dispatcher would cost about what the step saves
    assert _kernel(monkeypatch, "auto", tmp_path) is None


def test_auto_mode_with_an_extension_runs_its_step(
        monkeypatch: pytest.MonkeyPatch, aot_kernel_dir: Path) -> None:
    kernel = _kernel(monkeypatch, "auto", aot_kernel_dir)
    assert kernel is not None and type(kernel).__name__ == "builtin_function_or_method"


def test_python_mode_runs_the_python_step(monkeypatch: pytest.MonkeyPatch,
                                          tmp_path: Path) -> None:
    assert _kernel(monkeypatch, "python", tmp_path) is None
