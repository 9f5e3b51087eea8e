"""An AHRS loads its compiled kernels when it is bound to its streams, at the run's start.

Without an AOT extension a compiled kernel is numba compiling or loading it from its cache:
seconds and about 120 MB once per process. Loaded lazily at the first block of several
frames, that pause fell in the middle of a flight (the seed board's soak: numba loaded at
61 s, after a burst of bus errors), holding up every device. Each check runs in a child
process, since the compiled kernels are cached per process.
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest
from tests.support.kernels import cli_env

pytest.importorskip("numba", reason="the JIT backend is numba")

CHILD = '''
import sys
from imuhal.core.quantities import Quantity
from imuhal.core.samples import Frame
from imuhal.core.streams import StreamSpec
from imuhal.plugins.manager import load_registry
from imuhal_filters.common import fast
from imuhal_filters.madgwick.fast import madgwick_block, madgwick_rows

ahrs = load_registry().estimators.get("madgwick")({})
loaded_before = "numba" in sys.modules
ahrs.bind([StreamSpec("imu", Quantity.GYRO, Frame.SENSOR, 250.0, full_scale=9.0),
           StreamSpec("imu", Quantity.ACCEL, Frame.SENSOR, 250.0, full_scale=40.0)])
misses = fast._jitted.cache_info().misses
for kernel in (madgwick_block, madgwick_rows):
    fast._jitted(kernel)
print(loaded_before, "numba" in sys.modules, fast._jitted.cache_info().misses - misses)
'''


def test_binding_loads_the_row_kernel_and_block_step(tmp_path: Path) -> None:
    # ``auto`` with no AOT extension in its folder: the JIT, loaded only where a kernel is
    # used (not for the per-sample step, which only the extension runs in ``auto``)
    env = cli_env(IMUHAL_KERNEL_DIR=str(tmp_path))
    done = subprocess.run([sys.executable, "-c", CHILD], capture_output=True, text=True,
                          env=env, timeout=600, check=False)
    assert done.returncode == 0, done.stderr
    # numba not loaded by building the estimator, loaded by binding it, and neither kernel
    # compiled afterwards (0 new cache misses)
    assert done.stdout.split() == ["False", "True", "0"]
