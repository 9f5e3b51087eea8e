"""numba's on-disk cache of a JIT kernel is keyed by every module its code comes from.

numba itself notices an edit to the kernel's own file only; a kernel calling a helper kernel
of another module (the shared gate and row loop of common/fast_ahrs.py) must not run the
cached code of the helper's old source. A kernel and its helper in two throw-away modules,
each run in a child process (numba's cache is per process and on disk).
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest
from tests.support.kernels import cli_env

from imuhal_filters.common.fast import Kernel, inline_kernel

pytest.importorskip("numba", reason="the cache checked here is numba's")

HELPER = '''
from imuhal_filters.common.fast import jit


def _scale(x):
    return x * {factor}


scale = jit(_scale)
'''

KERNEL = '''
from imuhal_filters.common.fast import jit
from jitcase_helper import scale


def _scaled(x):
    return scale(x)


scaled = jit(_scaled, returns="f8", x="f8")
'''

CHILD = '''
from imuhal_filters.common import fast
from jitcase_kernel import scaled
value = scaled(2.0)
print(value, sum(fast._jitted(scaled).stats.cache_hits.values()))
'''


def _run(src: Path) -> tuple[float, int]:
    done = subprocess.run([sys.executable, "-c", CHILD], capture_output=True, text=True,
                          timeout=120, env=cli_env(IMUHAL_KERNELS="jit", PYTHONPATH=str(src)))
    assert done.returncode == 0, done.stderr
    value, hits = done.stdout.split()
    return float(value), int(hits)


def test_a_cached_jit_kernel_is_reused_until_a_helper_in_another_module_changes(
        tmp_path: Path) -> None:
    (tmp_path / "jitcase_kernel.py").write_text(KERNEL)
    helper = tmp_path / "jitcase_helper.py"
    helper.write_text(HELPER.format(factor=2.0))
    assert _run(tmp_path) == (4.0, 0)   # compiled, saved
    assert _run(tmp_path) == (4.0, 1)   # loaded from the cache
    helper.write_text(HELPER.format(factor=3.0))  # the kernel's own file is untouched
    assert _run(tmp_path) == (6.0, 0)   # compiled afresh, not the cached 4.0


def test_an_inlined_helper_is_cached_and_reread_like_any_other(tmp_path: Path) -> None:
    (tmp_path / "jitcase_kernel.py").write_text(KERNEL)
    helper = tmp_path / "jitcase_helper.py"
    inlined = HELPER.replace("import jit", "import inline_kernel, jit").replace(
        "scale = jit(_scale)", "scale = inline_kernel(jit(_scale))")
    helper.write_text(inlined.format(factor=2.0))
    assert _run(tmp_path) == (4.0, 0)
    assert _run(tmp_path) == (4.0, 1)
    helper.write_text(inlined.format(factor=3.0))
    assert _run(tmp_path) == (6.0, 0)


def test_only_a_helper_kernel_can_be_inlined() -> None:
    def _double(x: float) -> float:
        return 2.0 * x

    called_from_python = Kernel(_double, "f8", {"x": "f8"})  # not registered: no jit()
    with pytest.raises(TypeError, match="called from Python"):
        inline_kernel(called_from_python)
    helper = Kernel(_double)
    assert inline_kernel(helper).inline == "always"
