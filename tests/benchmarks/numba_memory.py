"""Where the peak memory of ``imuhal estimate`` with numba comes from (plain script; not
collected by pytest).

Run:  .venv/bin/python -m tests.benchmarks.numba_memory [--rows 1000]

Each stage runs in a fresh child process and reports its peak RSS (``VmHWM``, Linux): the
interpreter with numpy; with scipy as well (numba's ``__init__`` imports scipy, when it is
installed, to check its version); with numba imported; with one trivial ``njit(cache=True)``
kernel loaded from numba's on-disk cache (the second of two runs, so nothing is compiled);
then ``imuhal estimate madgwick`` on a short ``--rows`` log with numba's JIT and in pure
Python (the difference is numba's fixed cost in the command); then, with the kernels built
ahead of time (``imuhal kernels build`` into a temporary directory), one kernel called from
the extension and ``imuhal estimate`` on it (no numba loaded). docs/performance.md keeps the
figures.
"""

from __future__ import annotations

import argparse
import importlib.util
import os
import subprocess
import sys
import tempfile
from pathlib import Path

from tests.benchmarks.bench_all import build_kernels, run_estimate, write_log

_HWM = ("import sys;print([l.split()[1] for l in open('/proc/self/status')"
        " if l.startswith('VmHWM')][0], file=sys.stderr)")

_KERNEL = '''import numba


@numba.njit(cache=True)
def add(a, b):
    return a + b
'''


def peak_mb(code: str, *, cwd: Path | None = None, env: dict[str, str] | None = None) -> float:
    """Peak RSS (MB) of a child interpreter that runs ``code``."""
    proc = subprocess.run([sys.executable, "-c", f"{code}\n{_HWM}"], capture_output=True,
                          text=True, check=True, cwd=cwd, env={**os.environ, **(env or {})})
    return int(proc.stderr.strip().splitlines()[-1]) / 1024


def stages(rows: int) -> list[tuple[str, float]]:
    out = [("python + numpy", peak_mb("import numpy"))]
    if importlib.util.find_spec("scipy") is not None:
        out.append(("python + numpy + scipy", peak_mb("import numpy, scipy")))
    out.append(("python + numba (imports numpy and scipy)", peak_mb("import numba")))
    with tempfile.TemporaryDirectory() as tmp:
        work = Path(tmp)
        (work / "kernel_mod.py").write_text(_KERNEL)
        env = {"NUMBA_CACHE_DIR": str(work / "cache"), "PYTHONPATH": str(work)}
        code = "import kernel_mod; kernel_mod.add(1.0, 2.0)"
        peak_mb(code, cwd=work, env=env)  # compiles and writes the cache
        out.append(("python + numba + one trivial cached kernel",
                     peak_mb(code, cwd=work, env=env)))
        log, result = work / "log.csv", work / "out.csv"
        write_log(log, rows)
        run_estimate(log, result, "jit")  # the kernels' cache is warm for the measured run
        out.append((f"imuhal estimate madgwick, {rows} rows, numba JIT",
                    run_estimate(log, result, "jit")[1]))
        out.append((f"imuhal estimate madgwick, {rows} rows, pure Python",
                    run_estimate(log, result, "python")[1]))
        kernels = work / "kernels"
        failed = build_kernels(kernels)
        if failed is None:
            probe = ("import numpy as np; from imuhal_filters.vario.fast import baro_rows; "
                     "baro_rows(np.zeros(5), 1.0, 1.0, np.zeros(4), np.full(4, 0.1), "
                     "np.zeros((4, 2))); import sys; assert 'numba' not in sys.modules")
            aot_env = {"IMUHAL_KERNEL_DIR": str(kernels), "IMUHAL_KERNELS": "aot"}
            out.append(("python + numpy + imuhal's AOT kernel extension, one call",
                        peak_mb(probe, env=aot_env)))
            out.append((f"imuhal estimate madgwick, {rows} rows, AOT extension",
                        run_estimate(log, result, "aot", kernels)[1]))
        else:
            print(f"no AOT rows: {failed}", file=sys.stderr)
    return out


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--rows", type=int, default=1000, help="rows of the estimate log")
    args = p.parse_args(argv)
    print("| stage | peak RSS (MB) |\n| --- | ---: |")
    for name, mb in stages(args.rows):
        print(f"| {name} | {mb:.1f} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
