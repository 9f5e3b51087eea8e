"""`imuhal estimate madgwick` of two trees on one log, alternately (plain script; not collected
by pytest).

Run:  .venv/bin/python -m tests.benchmarks.estimate_trees --other TREE --other-kernels KDIR
      [--kernels KDIR] [--rows 2000000] [--rounds 2]

Issue 24's target for ``imuhal estimate`` is a ratio against the code of the day it was filed
(at least 3 x its rows per CPU second); the machine's speed moves between days, so the ratio
is measured in one run: this tree and ``--other`` (an exported copy of another commit, e.g.
``git archive fe1b157 | tar -x -C TREE``) each run ``imuhal estimate madgwick`` in a child
process on the same generated 250 Hz 9-DOF log (bench_all's), with the AOT extension each
was built with (``IMUHAL_KERNEL_DIR=KDIR imuhal kernels build``, run from the tree), in
alternating order, after a short warm-up run each (bytecode cache written). The other tree
runs with ``PYTHONPATH`` at its ``src`` and ``plugins``, from a neutral directory, in this
venv. Each line: rows per CPU second of the child, its peak RSS, and the ratio of this tree
to the other in the same round.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
from pathlib import Path

from tests.benchmarks.bench_all import write_log

CODE = ("import sys,time;from imuhal.cli.main import main;"
        "t=time.process_time();rc=main(sys.argv[1:]);"
        "hwm=[l.split()[1] for l in open('/proc/self/status') if l.startswith('VmHWM')];"
        "print(time.process_time()-t,hwm[0],'numba' in sys.modules,file=sys.stderr);"
        "sys.exit(rc)")
"""The child: CPU seconds of ``main``, peak RSS (kB), whether numba was imported."""


def run(log: Path, out: Path, kernels: Path, pythonpath: str | None) -> tuple[float, float]:
    """CPU s and peak RSS (MB) of ``imuhal estimate madgwick LOG`` on the AOT extension in
    ``kernels``; ``pythonpath``: the other tree's ``src:plugins`` (None: this tree)."""
    env = {k: v for k, v in os.environ.items()
           if k not in ("IMUHAL_NO_JIT", "IMUHAL_KERNELS", "IMUHAL_FAST_CSV",
                        "PYTHONDONTWRITEBYTECODE", "PYTHONPATH")}
    env.update(IMUHAL_KERNELS="aot", IMUHAL_KERNEL_DIR=str(kernels), IMUHAL_FAST_CSV="1")
    if pythonpath is not None:
        env["PYTHONPATH"] = pythonpath
    proc = subprocess.run([sys.executable, "-c", CODE, "estimate", "madgwick", str(log),
                           "-o", str(out)], capture_output=True, text=True, check=False,
                          env=env, cwd=tempfile.gettempdir())
    if proc.returncode != 0:
        raise SystemExit(f"imuhal estimate failed:\n{proc.stderr}")
    cpu_s, rss_kb, numba_loaded = proc.stderr.strip().splitlines()[-1].split()
    if numba_loaded != "False":
        raise SystemExit("imuhal estimate on the AOT extension imported numba")
    return float(cpu_s), int(rss_kb) / 1024


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--other", type=Path, required=True, help="the other tree (exported)")
    p.add_argument("--other-kernels", type=Path, required=True,
                   help="the AOT extension built from the other tree")
    p.add_argument("--kernels", type=Path, required=True,
                   help="the AOT extension built from this tree")
    p.add_argument("--rows", type=int, default=2_000_000)
    p.add_argument("--rounds", type=int, default=2)
    args = p.parse_args(argv)
    other = f"{args.other.resolve() / 'src'}:{args.other.resolve() / 'plugins'}"
    trees = {"this tree": (args.kernels, None), f"{args.other.name}": (args.other_kernels, other)}
    with tempfile.TemporaryDirectory() as tmp:
        log, small, out = Path(tmp) / "log.csv", Path(tmp) / "small.csv", Path(tmp) / "out.csv"
        write_log(log, args.rows)
        write_log(small, 1000)
        for kernels, path in trees.values():
            run(small, out, kernels, path)
        for i in range(args.rounds):
            rates = {}
            for name in (list(trees) if i % 2 == 0 else list(trees)[::-1]):
                kernels, path = trees[name]
                cpu, rss = run(log, out, kernels, path)
                rates[name] = args.rows / cpu
                print(f"round {i + 1}, {name}: {rates[name]:,.0f} rows/s (cpu {cpu:.2f} s), "
                      f"peak RSS {rss:.1f} MB, load {os.getloadavg()[0]:.1f}", flush=True)
            mine, theirs = rates["this tree"], rates[args.other.name]
            print(f"round {i + 1}: this tree / {args.other.name} = {mine / theirs:.2f}",
                  flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
