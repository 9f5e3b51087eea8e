"""imuhal's speed in one command, next to peers measured in the same run (not collected by pytest).

Run:  .venv/bin/python -m tests.benchmarks.bench_all [--rows 2000000] [--board-s 60]
      [--samples 20000] [--markdown]

Install the peers with ``pip install -e ".[bench]"`` (vqf, imufusion, ahrs); a hand-written
pure-Python Madgwick is always measured. Every figure is CPU time of this process (or of the
child process, for ``imuhal estimate``), so other jobs on a shared machine disturb it less;
ratios between rows of one run are what to compare across machines.

Sections:

* per sample: for every AHRS, the filter core (``_step`` on a prepared step: the kernel
  and its diagnostics), ``update()`` and ``process()`` (the pipeline's path: one accel, one
  mag and one gyro sample per step), in us per step, and ``process / core``; the core and
  these rows on the Python step (``IMUHAL_KERNELS=python``), then the compiled per-sample step
  alone and ``update()``/``process()`` on it, per backend (numba's JIT and the AOT extension
  forced; ``auto`` takes the AOT one only);
* batch: every estimator's batch function in samples/s (the compiled kernel when numba is
  installed, see ``imuhal_filters.common.fast``), next to ``vqf.VQF.updateBatch``;
* ``imuhal estimate madgwick`` on a generated ``--rows`` CSV, in a child process: rows/s and
  peak RSS (``VmHWM`` of the child, Linux), with each kernel backend: the AOT extension
  (``imuhal kernels build`` into a temporary directory first), numba's JIT, pure Python;
  beside the AOT row, in the same run, the same command with the CSV read and written per
  cell (``IMUHAL_FAST_CSV=0``: the csv module, ``float`` and ``repr``, the path before
  issue 24) and its peak RSS on a log a tenth as long (memory flat in the log's length).
  The child runs with Python's bytecode cache on, as an installed imuhal does (a first run
  on a short log writes it), whatever ``PYTHONDONTWRITEBYTECODE`` says here;
* the emulated seed board with its estimators: x real time by CPU time (the least CPU of
  three runs), next to the bare scenario truth at 250 Hz, and per IMU sample; what of that
  the emulation costs (less the hardware path's CPU per IMU sample, measured next), and
  its layers (simulation, chip emulators, bus glue, fault layer) sampled on CPU time
  (tests/benchmarks/emulation_split.py);
* the hardware path: the same board's drivers, decoding, calibration, mount rotation and
  estimators replayed from a recording of its bus traffic (no simulation, no emulators), in
  us of CPU per IMU sample (tests/benchmarks/bench_hardware_path.py);
* blocks (issue 24): the GY-91 emulated and through the hardware path with one frame per
  block and with its MPU-9250's FIFO read in blocks of 10 frames, side by side
  (tests/benchmarks/bench_blocks.py), and Madgwick's row kernel on fusion steps of n
  frames against the same frames one by one (tests/benchmarks/bench_block_parts.py);
* the board and blocks sections run as a board does by default: ``auto`` kernels, with the
  AOT extension built from the sources first (the compiled per-sample steps). The load
  average at the end of the run is printed with the table (stderr).

OPENBLAS_CORETYPE may be set on this machine (an old OpenBLAS needs it); it only matters to
BLAS calls, which none of the measured paths make, and it is left as it is.
"""

from __future__ import annotations

import argparse
import contextlib
import importlib.util
import itertools
import math
import os
import resource
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")

import numpy as np

from imuhal.core.samples import AccelSample, Frame, GyroSample, MagSample
from imuhal.plugins.manager import Registry, load_registry
from imuhal.profile.model import BoardProfile

ROOT = Path(__file__).resolve().parents[2]
AHRS_NAMES = ("madgwick", "mahony", "imufilter", "freescale-6dof", "freescale-9dof")
RATE_HZ = 250.0


@dataclass
class Row:
    section: str
    case: str
    value: float
    unit: str
    peer: str = ""
    ratio: float | None = None
    target: str = ""


def cpu_per_call(fn: Callable[[int], None], n: int, repeat: int = 3) -> float:
    """Best-of-``repeat`` CPU seconds per iteration of ``fn(n)``."""
    best = math.inf
    for _ in range(repeat):
        t0 = time.process_time()
        fn(n)
        best = min(best, time.process_time() - t0)
    return best / n


def motion(n: int, seed: int = 1) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A gently moving board: gyro rad/s, specific force m/s^2 (NED, level az = -9.81), uT."""
    rng = np.random.default_rng(seed)
    t = np.arange(n) / RATE_HZ
    gyro = np.stack([0.3 * np.sin(0.7 * t), 0.2 * np.sin(0.5 * t + 1), 0.1 * np.cos(0.3 * t)],
                    axis=1) + rng.normal(0, 0.01, (n, 3))
    accel = np.array([0.0, 0.0, -9.81]) + rng.normal(0, 0.2, (n, 3))
    mag = np.array([20.0, 1.0, 45.0]) + rng.normal(0, 0.5, (n, 3))
    return gyro, accel, mag


# --------------------------------------------------------------------------- peers
def plain_madgwick(q: list[float], g: tuple[float, float, float], a: tuple[float, float, float],
                   m: tuple[float, float, float], beta: float, dt: float) -> list[float]:
    """The x-io MARG update as one would write it by hand in Python (the always-there peer)."""
    q0, q1, q2, q3 = q
    gx, gy, gz = g
    ax, ay, az = a
    mx, my, mz = m
    qd0 = 0.5 * (-q1 * gx - q2 * gy - q3 * gz)
    qd1 = 0.5 * (q0 * gx + q2 * gz - q3 * gy)
    qd2 = 0.5 * (q0 * gy - q1 * gz + q3 * gx)
    qd3 = 0.5 * (q0 * gz + q1 * gy - q2 * gx)
    r = 1.0 / math.sqrt(ax * ax + ay * ay + az * az)
    ax, ay, az = ax * r, ay * r, az * r
    r = 1.0 / math.sqrt(mx * mx + my * my + mz * mz)
    mx, my, mz = mx * r, my * r, mz * r
    hx = (mx * (q0 * q0 + q1 * q1 - q2 * q2 - q3 * q3) + 2 * my * (q1 * q2 - q0 * q3)
          + 2 * mz * (q1 * q3 + q0 * q2))
    hy = (2 * mx * (q1 * q2 + q0 * q3) + my * (q0 * q0 - q1 * q1 + q2 * q2 - q3 * q3)
          + 2 * mz * (q2 * q3 - q0 * q1))
    bx = 2 * math.sqrt(hx * hx + hy * hy)
    bz = 2 * (2 * mx * (q1 * q3 - q0 * q2) + 2 * my * (q2 * q3 + q0 * q1)
              + mz * (q0 * q0 - q1 * q1 - q2 * q2 + q3 * q3))
    f1 = 2 * (q1 * q3 - q0 * q2) - ax
    f2 = 2 * (q0 * q1 + q2 * q3) - ay
    f3 = 2 * (0.5 - q1 * q1 - q2 * q2) - az
    f4 = bx * (0.5 - q2 * q2 - q3 * q3) + bz * (q1 * q3 - q0 * q2) - mx
    f5 = bx * (q1 * q2 - q0 * q3) + bz * (q0 * q1 + q2 * q3) - my
    f6 = bx * (q0 * q2 + q1 * q3) + bz * (0.5 - q1 * q1 - q2 * q2) - mz
    s0 = -2 * q2 * f1 + 2 * q1 * f2 - bz * q2 * f4 + (-bx * q3 + bz * q1) * f5 + bx * q2 * f6
    s1 = (2 * q3 * f1 + 2 * q0 * f2 - 4 * q1 * f3 + bz * q3 * f4 + (bx * q2 + bz * q0) * f5
          + (bx * q3 - 2 * bz * q1) * f6)
    s2 = (-2 * q0 * f1 + 2 * q3 * f2 - 4 * q2 * f3 + (-2 * bx * q2 - bz * q0) * f4
          + (bx * q1 + bz * q3) * f5 + (bx * q0 - 2 * bz * q2) * f6)
    s3 = (2 * q1 * f1 + 2 * q2 * f2 + (-2 * bx * q3 + bz * q1) * f4 + (-bx * q0 + bz * q2) * f5
          + bx * q1 * f6)
    r = beta / math.sqrt(s0 * s0 + s1 * s1 + s2 * s2 + s3 * s3)
    q0 += (qd0 - r * s0) * dt
    q1 += (qd1 - r * s1) * dt
    q2 += (qd2 - r * s2) * dt
    q3 += (qd3 - r * s3) * dt
    r = 1.0 / math.sqrt(q0 * q0 + q1 * q1 + q2 * q2 + q3 * q3)
    return [q0 * r, q1 * r, q2 * r, q3 * r]


def peer_rows(n: int, gyro: np.ndarray, accel: np.ndarray, mag: np.ndarray) -> list[Row]:
    rows: list[Row] = []
    g = [tuple(r) for r in gyro.tolist()]
    a = [tuple(r) for r in (-accel).tolist()]
    m = [tuple(r) for r in mag.tolist()]

    def plain(k: int) -> None:
        q = [1.0, 0.0, 0.0, 0.0]
        for i in range(k):
            q = plain_madgwick(q, g[i], a[i], m[i], 0.1, 1 / RATE_HZ)

    rows.append(Row("peer", "plain-Python Madgwick 9-DOF loop", cpu_per_call(plain, n) * 1e6,
                    "us/sample"))
    try:
        import vqf
    except ImportError:
        print("vqf not installed: pip install -e '.[bench]'", file=sys.stderr)
    else:
        gyr = np.ascontiguousarray(gyro)
        acc = np.ascontiguousarray(-accel)
        mg = np.ascontiguousarray(mag)

        def vqf_loop(k: int) -> None:
            f = vqf.VQF(1 / RATE_HZ)
            for i in range(k):
                f.update(gyr[i], acc[i], mg[i])

        rows.append(Row("peer", "vqf.VQF.update loop 9-DOF", cpu_per_call(vqf_loop, n) * 1e6,
                        "us/sample"))

        def vqf_batch(k: int) -> None:
            vqf.VQF(1 / RATE_HZ).updateBatch(gyr[:k], acc[:k], mg[:k])

        big = max(n, 100_000)
        reps = math.ceil(big / len(gyr))
        gyr, acc, mg = (np.ascontiguousarray(np.tile(x, (reps, 1))) for x in (gyr, acc, mg))
        rows.append(Row("peer", "vqf.VQF.updateBatch 9-DOF",
                        1.0 / cpu_per_call(vqf_batch, big), "samples/s"))
    try:
        import imufusion
    except ImportError:
        print("imufusion not installed", file=sys.stderr)
    else:
        gdeg = np.degrees(gyro)
        ag = -accel / 9.80665

        def fusion(k: int) -> None:
            ahrs = imufusion.Ahrs()
            for i in range(k):
                ahrs.update(gdeg[i], ag[i], mag[i])

        rows.append(Row("peer", "imufusion.Ahrs.update loop 9-DOF",
                        cpu_per_call(fusion, n) * 1e6, "us/sample"))
    try:
        from ahrs.filters import Madgwick as AhrsMadgwick
    except ImportError:
        print("ahrs not installed", file=sys.stderr)
    else:
        acc2 = -accel

        def ahrs_loop(k: int) -> None:
            f = AhrsMadgwick(frequency=RATE_HZ)
            q = np.array([1.0, 0, 0, 0])
            for i in range(k):
                q = f.updateMARG(q, gyro[i], acc2[i], mag[i])

        rows.append(Row("peer", "ahrs.filters.Madgwick.updateMARG loop",
                        cpu_per_call(ahrs_loop, min(n, 5000)) * 1e6, "us/sample"))
    return rows


# --------------------------------------------------------------------------- imuhal
@contextlib.contextmanager
def kernels(backend: str, aot_dir: Path | None = None) -> Iterator[None]:
    """``IMUHAL_KERNELS=backend`` (and the AOT extension's directory) for the block; the
    estimators made inside pick their per-sample step then (at reset)."""
    saved = {k: os.environ.get(k) for k in ("IMUHAL_KERNELS", "IMUHAL_KERNEL_DIR")}
    os.environ["IMUHAL_KERNELS"] = backend
    if aot_dir is not None:
        os.environ["IMUHAL_KERNEL_DIR"] = str(aot_dir)
    try:
        yield
    finally:
        for k, v in saved.items():
            if v is None:
                os.environ.pop(k, None)
            else:
                os.environ[k] = v


def estimator_rows(n: int, gyro: np.ndarray, accel: np.ndarray, mag: np.ndarray,
                   vqf_loop_us: float | None, vqf_batch: float | None,
                   aot_dir: Path | None = None) -> list[Row]:
    from imuhal_filters.common import fast
    from imuhal_filters.common.ahrs import ImuStep
    from imuhal_filters.common.gate import gravity_positive_g

    registry = load_registry()
    rows: list[Row] = []
    g = [tuple(r) for r in gyro.tolist()]
    a = [tuple(r) for r in accel.tolist()]
    m = [tuple(r) for r in mag.tolist()]
    dt = 1 / RATE_HZ
    step_ns = round(dt * 1e9)
    samples = []
    for i in range(n):
        t = 1_000_000 + i * step_ns
        samples.append((AccelSample(t_ns=t, device="b", frame=Frame.BODY_NED, accel_m_s2=a[i]),
                        MagSample(t_ns=t, device="b", frame=Frame.BODY_NED, mag_ut=m[i]),
                        GyroSample(t_ns=t, device="b", frame=Frame.BODY_NED, gyro_rad_s=g[i])))
    for name in AHRS_NAMES:
        cls = registry.estimators.get(name)
        if name.startswith("freescale"):
            rows += freescale_rows(name, cls, samples, gyro, accel, mag)
            continue
        uses_mag = getattr(cls, "uses_mag", True)

        def make(cls=cls, uses_mag=uses_mag):  # type: ignore[no-untyped-def]
            est = cls(cls.Settings())
            est.update(g[0], a[0], m[0] if uses_mag else None, dt)  # aligned
            return est

        steps = [ImuStep(g[i], gravity_positive_g(a[i]), m[i] if uses_mag else None, dt)
                 for i in range(n)]

        def core(k: int, est_factory=make, steps=steps) -> None:
            est = est_factory()
            for i in range(k):
                est._step(steps[i])

        def update(k: int, est_factory=make, uses_mag=uses_mag) -> None:
            est = est_factory()
            for i in range(k):
                est.update(g[i], a[i], m[i] if uses_mag else None, dt)

        def process(k: int, est_factory=make) -> None:
            est = est_factory()
            for i in range(k):
                acc, mg, gy = samples[i]
                est.process(acc)
                est.process(mg)
                est.process(gy)

        def compiled_step(k: int, est_factory=make, uses_mag=uses_mag) -> None:
            est = est_factory()
            step = est._compiled_step
            for i in range(k):
                step(g[i], a[i], m[i] if uses_mag else None, dt, a[i])

        # the Python step (the core of the ratio) and the per-sample path on it
        with kernels("python"):
            c = cpu_per_call(core, n) * 1e6
            u = cpu_per_call(update, n) * 1e6
            p = cpu_per_call(process, n) * 1e6
        rows.append(Row("per sample", f"{name} core (_step)", c, "us/sample"))
        rows.append(Row("per sample", f"{name} update()", u, "us/sample", "core", u / c))
        rows.append(Row("per sample", f"{name} process()", p, "us/sample", "core", p / c,
                        "<= 1.3"))
        if name == "madgwick" and vqf_loop_us:
            rows.append(Row("per sample", "madgwick process()", p, "us/sample", "vqf loop",
                            p / vqf_loop_us, "<= 6"))
        # the compiled per-sample step, on each backend forced (auto uses only the AOT one)
        for backend in ("jit", "aot"):
            if (backend == "jit" and not fast.numba_installed()) or (
                    backend == "aot" and aot_dir is None):
                continue
            with kernels(backend, aot_dir):
                compiled_step(100)  # compile or load outside the timing
                cs = cpu_per_call(compiled_step, n) * 1e6
                cu = cpu_per_call(update, n) * 1e6
                cp = cpu_per_call(process, n) * 1e6
            rows.append(Row("per sample", f"{name} compiled step ({backend})", cs, "us/sample",
                            "core", cs / c))
            rows.append(Row("per sample", f"{name} update(), {backend} step", cu, "us/sample",
                            "core", cu / c))
            rows.append(Row("per sample", f"{name} process(), {backend} step", cp, "us/sample",
                            "core", cp / c, "<= 1.3"))
            rows.append(Row("per sample", f"{name} process(), {backend} step", cp, "us/sample",
                            "compiled step", cp / cs))
            if name == "madgwick" and vqf_loop_us:
                rows.append(Row("per sample", f"madgwick process(), {backend} step", cp,
                                "us/sample", "vqf loop", cp / vqf_loop_us, "<= 6"))
    rows += batch_rows(registry, gyro, accel, mag, vqf_batch, aot_dir)
    return rows


def freescale_rows(name: str, cls, samples: list, gyro: np.ndarray, accel: np.ndarray,
                   mag: np.ndarray) -> list[Row]:
    """The Freescale filters step once per oversampled window: their core is the Kalman
    step over the window (timed through the batch function), per input sample."""
    from imuhal_filters.freescale.batch import run_6dof, run_9dof

    n = len(samples)
    nine = name.endswith("9dof")
    ag, gd = -accel / 9.80665, np.degrees(gyro)

    def core(k: int) -> None:
        if nine:
            run_9dof(ag[:k], gd[:k], mag[:k], cls.Settings())
        else:
            run_6dof(ag[:k], gd[:k], cls.Settings())

    def process(k: int) -> None:
        est = cls(cls.Settings())
        for i in range(k):
            acc, mg, gy = samples[i]
            est.process(gy)
            est.process(acc)
            est.process(mg)

    os.environ["IMUHAL_NO_JIT"] = "1"  # the core is the Python Kalman step, as process() runs
    c = cpu_per_call(core, n) * 1e6
    del os.environ["IMUHAL_NO_JIT"]
    p = cpu_per_call(process, n) * 1e6
    return [Row("per sample", f"{name} core (batch)", c, "us/sample"),
            Row("per sample", f"{name} process()", p, "us/sample", "core", p / c, "<= 1.3")]


def batch_rows(registry, gyro: np.ndarray, accel: np.ndarray, mag: np.ndarray,
               vqf_batch: float | None, aot_dir: Path | None = None) -> list[Row]:
    """Pure Python and compiled (numba's JIT) batch throughput; for the AHRS also the AOT
    extension in ``aot_dir`` (built by :func:`build_kernels`) when given."""
    from imuhal_filters.common import fast
    from imuhal_filters.common.ahrs import AhrsEstimator
    from imuhal_filters.common.batch import run_batch

    rows: list[Row] = []
    n = len(gyro)
    for name in ("madgwick", "mahony", "imufilter"):
        cls = registry.estimators.get(name)

        def batch(k: int, cls=cls) -> None:  # type: ignore[no-untyped-def]
            run_batch(cls(cls.Settings()), gyro[:k], accel[:k], mag[:k], 1 / RATE_HZ)

        os.environ["IMUHAL_NO_JIT"] = "1"
        py = 1.0 / cpu_per_call(batch, n, repeat=2)
        del os.environ["IMUHAL_NO_JIT"]
        rows.append(Row("batch", f"{name} run_batch 9-DOF, pure Python", py, "samples/s",
                        "vqf updateBatch" if vqf_batch else "",
                        py / vqf_batch if vqf_batch else None))
        if not fast.available() or cls._run_kernel is AhrsEstimator._run_kernel:
            continue  # no compiled kernel (yet) for this estimator
        batch(100)  # compile (or load the cached kernel) outside the timing
        big = np.tile(gyro, (10, 1)), np.tile(accel, (10, 1)), np.tile(mag, (10, 1))

        def compiled(k: int, cls=cls, big=big) -> None:  # type: ignore[no-untyped-def]
            run_batch(cls(cls.Settings()), big[0][:k], big[1][:k], big[2][:k], 1 / RATE_HZ)

        c = 1.0 / cpu_per_call(compiled, 10 * n, repeat=3)
        rows.append(Row("batch", f"{name} run_batch 9-DOF, compiled", c, "samples/s",
                        "vqf updateBatch" if vqf_batch else "",
                        c / vqf_batch if vqf_batch else None,
                        ">= 2" if name == "madgwick" else ""))
        rows.append(Row("batch", f"{name} compiled / pure Python", c / py, "x", "", None,
                        "" if name == "madgwick" else ">= 10"))
        if aot_dir is not None:
            saved = os.environ["IMUHAL_KERNELS"], os.environ.get("IMUHAL_KERNEL_DIR")
            os.environ["IMUHAL_KERNELS"], os.environ["IMUHAL_KERNEL_DIR"] = "aot", str(aot_dir)
            compiled(100)
            a = 1.0 / cpu_per_call(compiled, 10 * n, repeat=3)
            os.environ["IMUHAL_KERNELS"] = saved[0]
            if saved[1] is None:
                del os.environ["IMUHAL_KERNEL_DIR"]
            else:
                os.environ["IMUHAL_KERNEL_DIR"] = saved[1]
            rows.append(Row("batch", f"{name} run_batch 9-DOF, AOT extension", a, "samples/s",
                            "JIT (row above)", a / c))
    rows += freescale_batch_rows(gyro, accel, mag, vqf_batch)
    rows += vario_batch_rows(n)
    return rows


def freescale_batch_rows(gyro: np.ndarray, accel: np.ndarray, mag: np.ndarray,
                         vqf_batch: float | None) -> list[Row]:
    """``run_9dof``/``run_6dof`` (default settings), pure Python and compiled (numba)."""
    from imuhal_filters.common import fast
    from imuhal_filters.freescale.batch import run_6dof, run_9dof
    from imuhal_filters.freescale.settings import Freescale6DofSettings, Freescale9DofSettings

    n = len(gyro)
    ag, gd = -np.tile(accel, (10, 1)) / 9.80665, np.degrees(np.tile(gyro, (10, 1)))
    big_mag = np.tile(mag, (10, 1))
    cases = {"freescale run_9dof": lambda k: run_9dof(ag[:k], gd[:k], big_mag[:k],
                                                      Freescale9DofSettings()),
             "freescale run_6dof": lambda k: run_6dof(ag[:k], gd[:k], Freescale6DofSettings())}
    rows: list[Row] = []
    for name, fn in cases.items():
        os.environ["IMUHAL_NO_JIT"] = "1"
        py = 1.0 / cpu_per_call(fn, min(n, 5000), repeat=2)
        del os.environ["IMUHAL_NO_JIT"]
        rows.append(Row("batch", f"{name}, pure Python", py, "samples/s",
                        "vqf updateBatch" if vqf_batch else "",
                        py / vqf_batch if vqf_batch else None))
        if not fast.available():
            continue
        fn(800)  # compile (or load the cached kernel) outside the timing
        c = 1.0 / cpu_per_call(fn, 10 * n, repeat=3)
        rows.append(Row("batch", f"{name}, compiled", c, "samples/s",
                        "vqf updateBatch" if vqf_batch else "",
                        c / vqf_batch if vqf_batch else None))
        rows.append(Row("batch", f"{name} compiled / pure Python", c / py, "x", "", None,
                        ">= 10"))
    return rows


def vario_batch_rows(n: int) -> list[Row]:
    """vario-kf3 and baro-vario batch loops, pure Python and compiled (numba)."""
    from imuhal_filters.common import fast
    from imuhal_filters.vario.batch import run_baro_batch
    from imuhal_filters.vario.batch import run_batch as vario_batch

    z = np.cumsum(np.random.default_rng(3).normal(0, 0.1, 10 * n))
    a = np.random.default_rng(4).normal(0, 0.3, 10 * n)
    cases = {"vario-kf3 run_batch": lambda k: vario_batch(z[:k], a[:k], 1 / RATE_HZ),
             "baro-vario run_baro_batch": lambda k: run_baro_batch(z[:k], 1 / RATE_HZ)}
    rows: list[Row] = []
    for name, fn in cases.items():
        os.environ["IMUHAL_NO_JIT"] = "1"
        py = 1.0 / cpu_per_call(fn, n, repeat=2)
        del os.environ["IMUHAL_NO_JIT"]
        rows.append(Row("batch", f"{name}, pure Python", py, "samples/s"))
        if not fast.available():
            continue
        fn(100)  # compile (or load the cached kernel) outside the timing
        c = 1.0 / cpu_per_call(fn, 10 * n, repeat=3)
        rows.append(Row("batch", f"{name}, compiled", c, "samples/s"))
        rows.append(Row("batch", f"{name} compiled / pure Python", c / py, "x", "", None,
                        ">= 10"))
    return rows


def write_log(path: Path, rows: int) -> None:
    """A 250 Hz 9-DOF log in the CSV form ``imuhal estimate`` reads (chunks of 100k rows)."""
    with path.open("w") as f:
        f.write("t_s,gx_rad_s,gy_rad_s,gz_rad_s,ax_m_s2,ay_m_s2,az_m_s2,mx_ut,my_ut,mz_ut\n")
        done = 0
        while done < rows:
            k = min(100_000, rows - done)
            gyro, accel, mag = motion(k, seed=done)
            t = (done + np.arange(k)) / RATE_HZ
            block = np.column_stack([t, gyro, accel, mag])
            np.savetxt(f, block, delimiter=",", fmt="%.9g")
            done += k


BEFORE_ESTIMATE_US_ROW = 44.9
"""``imuhal estimate madgwick`` CPU per row before issue 13 (docs/performance.md), the base of
the 4 x target: that code is gone, so it cannot be measured in the same run."""


def run_estimate(log: Path, out: Path, backend: str = "auto",
                 kernel_dir: Path | None = None, fast_csv: bool = True) -> tuple[float, float]:
    """CPU seconds and peak RSS (MB) of ``imuhal estimate madgwick`` in a child process, with
    the kernel backend forced (``IMUHAL_KERNELS``: aot, jit, python; auto: as installed) and
    the CSV read and written a block at a time (``fast_csv``) or per cell."""
    # VmHWM, not ru_maxrss: Linux keeps ru_maxrss across exec, so a child's would start
    # at this (larger) process's peak
    code = ("import sys,time;from imuhal.cli.main import main;"
            "t=time.process_time();rc=main(sys.argv[1:]);"
            "hwm=[l.split()[1] for l in open('/proc/self/status') if l.startswith('VmHWM')];"
            "print(time.process_time()-t,hwm[0],'numba' in sys.modules,file=sys.stderr);"
            "sys.exit(rc)")
    env = {k: v for k, v in os.environ.items()
           if k not in ("IMUHAL_NO_JIT", "IMUHAL_KERNELS", "IMUHAL_FAST_CSV",
                        "PYTHONDONTWRITEBYTECODE")}
    env["IMUHAL_KERNELS"] = backend
    env["IMUHAL_FAST_CSV"] = "1" if fast_csv else "0"
    if kernel_dir is not None:
        env["IMUHAL_KERNEL_DIR"] = str(kernel_dir)
    proc = subprocess.run([sys.executable, "-c", code, "estimate", "madgwick", str(log),
                           "-o", str(out)], capture_output=True, text=True, check=False,
                          env=env)
    if proc.returncode != 0:
        raise SystemExit(f"imuhal estimate failed:\n{proc.stderr}")
    cpu_s, rss_kb, numba_loaded = proc.stderr.strip().splitlines()[-1].split()
    if backend in ("aot", "python") and numba_loaded != "False":
        raise SystemExit(f"imuhal estimate with IMUHAL_KERNELS={backend} imported numba")
    return float(cpu_s), int(rss_kb) / 1024


def build_kernels(directory: Path) -> str | None:
    """``imuhal kernels build`` into ``directory`` (the sources as they are now); the error
    line when it cannot build here (no numba, no C compiler)."""
    proc = subprocess.run([sys.executable, "-m", "imuhal.cli.main", "kernels", "build"],
                          capture_output=True, text=True, check=False,
                          env={**os.environ, "IMUHAL_KERNEL_DIR": str(directory)})
    return None if proc.returncode == 0 else proc.stderr.strip()


ESTIMATE_TARGET_ROWS_S = 3 * 132_800
"""Issue 24: ``imuhal estimate madgwick`` at least 3 x the 132,800 rows per CPU second
measured when it was filed."""


def estimate_rows(n_rows: int, madgwick_update_us: float | None) -> list[Row]:
    """The three kernel backends of ``imuhal estimate`` on one log: the AOT extension (built
    first into a temporary kernel directory), numba's JIT (its cache warmed on a short log
    first, as an installed user's would be) and pure Python; beside the AOT row, the per-cell
    CSV path and the peak RSS on a tenth of the log."""
    with tempfile.TemporaryDirectory() as tmp:
        log = Path(tmp) / "log.csv"
        write_log(log, n_rows)
        out = Path(tmp) / "out.csv"
        size_mb = log.stat().st_size / 1e6
        rows: list[Row] = []
        kernels = Path(tmp) / "kernels"
        failed = build_kernels(kernels)
        small = Path(tmp) / "small.csv"
        write_log(small, 1000)
        run_estimate(small, out, "python")  # the bytecode cache written, as once installed
        head = f"imuhal estimate madgwick, {n_rows} rows ({size_mb:.0f} MB)"
        if failed is None:
            rows += aot_estimate_rows(head, log, out, kernels, n_rows, madgwick_update_us)
        else:
            print(f"no AOT rows: {failed}", file=sys.stderr)
        run_estimate(small, out, "jit")  # numba's cache warm for the measured run
        cpu, rss_mb = run_estimate(log, out, "jit")
        rows += estimate_table_rows("same, numba JIT (IMUHAL_KERNELS=jit)", n_rows, cpu, rss_mb,
                                    madgwick_update_us)
        cpu, rss_mb = run_estimate(log, out, "python")
        rows += estimate_table_rows("same, pure Python (IMUHAL_KERNELS=python)", n_rows, cpu,
                                    rss_mb, madgwick_update_us)
    return rows


def aot_estimate_rows(head: str, log: Path, out: Path, kernels: Path, n_rows: int,
                      madgwick_update_us: float | None) -> list[Row]:
    """The AOT extension's rows, the per-cell CSV path beside them (same backend, same log,
    one after the other) and the peak RSS on the first tenth of the log."""
    load = os.getloadavg()[0]
    cpu, rss_mb = run_estimate(log, out, "aot", kernels)
    cpu_cells, _ = run_estimate(log, out, "aot", kernels, fast_csv=False)
    tenth = log.with_name("tenth.csv")
    with log.open("rb") as src, tenth.open("wb") as dst:
        dst.writelines(itertools.islice(src, n_rows // 10 + 1))
    _, rss_tenth = run_estimate(tenth, out, "aot", kernels)
    load = max(load, os.getloadavg()[0])
    rows = estimate_table_rows(f"{head}, AOT extension (no numba loaded)", n_rows, cpu,
                               rss_mb, madgwick_update_us)
    rows[0] = Row("estimate", rows[0].case, rows[0].value, rows[0].unit,
                  "issue 24 target", rows[0].value / ESTIMATE_TARGET_ROWS_S,
                  f">= {ESTIMATE_TARGET_ROWS_S:,} (3 x 132,800)")
    rows.extend([
        Row("estimate", "  same, CSV per cell (IMUHAL_FAST_CSV=0)", n_rows / cpu_cells,
            "rows/s (cpu)"),
        Row("estimate", "  block CSV / per cell", cpu_cells / cpu, "x", "same run"),
        Row("estimate", f"  peak RSS at {n_rows // 10} rows", rss_tenth, "MB",
            f"peak RSS at {n_rows} rows / this", rss_mb / rss_tenth, "flat (<= 1.1)"),
        Row("estimate", "  load average (1 min, highest seen)", load, ""),
    ])
    return rows


def estimate_table_rows(case: str, n_rows: int, cpu: float, rss_mb: float,
                        madgwick_update_us: float | None) -> list[Row]:
    """``madgwick_update_us``: the ``update()`` row of this run, the per-row peer (None with
    ``--skip estimators``: no ratio, rather than one against a made-up figure)."""
    us_row = cpu / n_rows * 1e6
    return [
        Row("estimate", case, n_rows / cpu, "rows/s (cpu)"),
        Row("estimate", "  cpu per row", us_row, "us/row",
            "madgwick update()" if madgwick_update_us else "",
            us_row / madgwick_update_us if madgwick_update_us else None),
        Row("estimate", "  speed-up", BEFORE_ESTIMATE_US_ROW / us_row, "x",
            f"before ({BEFORE_ESTIMATE_US_ROW} us/row)", None, ">= 4"),
        Row("estimate", "  peak RSS", rss_mb, "MB", "", None, "<= 150 at 2,000,000 rows"),
    ]


def board_rows(duration_s: float) -> list[Row]:
    from imuhal.profile.loader import load_profile

    registry = load_registry()
    profile = load_profile(ROOT / "profiles" / "seed-paraglider-vario.yaml", registry)
    scenario = registry.scenarios.get("thermal")(None, seed=0)
    t0 = time.process_time()
    for k in range(int(duration_s * RATE_HZ)):
        scenario.truth(k / RATE_HZ)
    truth_cpu = time.process_time() - t0
    cpu = min(_emulated_cpu(profile, registry, duration_s) for _ in range(BOARD_REPEAT))
    return [Row("board", f"emulated seed board + estimators, {duration_s:g} s", duration_s / cpu,
                "x real time (cpu)", "bare truth at 250 Hz", cpu / truth_cpu, ">= 40 x real"),
            Row("board", "  the same per IMU sample", cpu / (duration_s * RATE_HZ) * 1e6,
                "us/IMU sample")]


BOARD_REPEAT = 3
"""Emulated runs per board row; the least CPU is kept, as for the hardware path."""


def _emulated_cpu(profile: BoardProfile, registry: Registry, duration_s: float) -> float:
    """CPU s of one emulated run of ``profile`` on ``thermal`` for ``duration_s``."""
    from imuhal.emulation import open_emulated

    with open_emulated(profile, registry, scenario="thermal") as pipeline:
        t0 = time.process_time()
        for _ in pipeline.events(duration_s):
            pass
        return time.process_time() - t0


def emulation_share_rows(rows: list[Row]) -> list[Row]:
    """What the emulation itself costs per IMU sample (the scenario's truth, the error
    models, the chip emulators and the emulated bus): the emulated board's CPU per IMU
    sample less its hardware path's (the same drivers, pipeline and estimators on a
    recording), both of this run; and the emulated board's x real time were the emulation
    free."""
    per_sample = next((r.value for r in rows if r.case == "  the same per IMU sample"), None)
    hardware = next((r.value for r in rows if r.case.startswith("hardware path")), None)
    if per_sample is None or hardware is None:
        return []
    return [Row("board", "  of it the emulation (emulated less the hardware path)",
                per_sample - hardware, "us/IMU sample", "the emulated board",
                (per_sample - hardware) / per_sample),
            Row("board", "  the emulated board were the emulation free",
                1e6 / RATE_HZ / hardware, "x real time (cpu)")]


def emulation_layer_rows(duration_s: float, rows: list[Row]) -> list[Row]:
    """The emulated board's CPU by layer (tests/benchmarks/emulation_split.py: one run of
    its own sampled on CPU time, each layer's share of it times the board row's CPU per
    IMU sample of this run): the simulation, the chip emulators, the bus glue, the fault
    layer; the rest is the hardware path."""
    from tests.benchmarks.emulation_split import LAYERS, measure

    per_sample = next((r.value for r in rows if r.case == "  the same per IMU sample"), None)
    if per_sample is None:
        return []
    _, samples = measure(duration_s, None)
    n = sum(samples.values()) or 1
    return [Row("board", f"  of it the {layer} (sampled)", per_sample * samples[layer] / n,
                "us/IMU sample", "the emulated board", samples[layer] / n)
            for layer in LAYERS if layer != "hardware path"]


def hardware_path_rows(duration_s: float) -> list[Row]:
    """The seed board's host side alone (drivers, decoding, calibration, mount rotation,
    estimators) from a recorded bus replay (tests/benchmarks/bench_hardware_path.py)."""
    from tests.benchmarks.bench_hardware_path import measure

    r = measure(duration_s)
    return [Row("board", f"hardware path (recorded bus replay, {duration_s:g} s)",
                r.us_per_imu_sample, "us/IMU sample", "decoding the recording alone",
                r.replay_cpu_s / r.decode_cpu_s, "<= 50"),
            Row("board", "  the same without the estimators", r.bare_us_per_imu_sample,
                "us/IMU sample"),
            Row("board", "  decoding the recording (not in the rows above)",
                r.decode_us_per_imu_sample, "us/IMU sample")]


def block_rows(duration_s: float) -> list[Row]:
    """Blocks (issue 24): the GY-91 with one frame per block and with its MPU-9250 read from
    the FIFO in blocks of 10 frames, emulated and through the recorded hardware path, in
    the same run (tests/benchmarks/bench_blocks.py). The seed board's MAX21100 has no FIFO
    reader yet: the FIFO rows are the GY-91's."""
    from tests.benchmarks.bench_blocks import measure_both

    one, fifo = measure_both(duration_s, 10)
    return [
        Row("blocks", f"gy91 emulated + estimators, {one.label}", one.x_real_time,
            "x real time (cpu)", "", None, ">= 40 x real"),
        Row("blocks", f"gy91 emulated + estimators, {fifo.label}", fifo.x_real_time,
            "x real time (cpu)", "one frame per block", fifo.x_real_time / one.x_real_time,
            ">= 150 x real"),
        Row("blocks", f"gy91 hardware path, {one.label}", one.us_per_imu_sample,
            "us/IMU sample", "", None, "<= 50"),
        Row("blocks", "  the same without the estimators", one.bare_us_per_imu_sample,
            "us/IMU sample"),
        Row("blocks", f"gy91 hardware path, {fifo.label}", fifo.us_per_imu_sample,
            "us/IMU sample", "one frame per block",
            fifo.us_per_imu_sample / one.us_per_imu_sample, "<= 10"),
        Row("blocks", "  the same without the estimators", fifo.bare_us_per_imu_sample,
            "us/IMU sample"),
    ]


def board_and_block_rows(duration_s: float, skip: list[str], kernel_dir: Path | None = None
                         ) -> list[Row]:
    """The board and blocks sections as a board runs by default: ``auto`` kernels with the
    AOT extension built from the sources as they are (the compiled per-sample steps; or
    the one ``kernel_dir`` holds, built from them), or numba's JIT row kernels and the
    Python step where it cannot be built (said on stderr)."""
    with tempfile.TemporaryDirectory() as tmp:
        failed = None if kernel_dir is not None else build_kernels(Path(tmp))
        if failed is not None:
            print(f"board and blocks rows without the AOT extension: {failed}",
                  file=sys.stderr)
        rows: list[Row] = []
        with kernels("auto", None if failed is not None else kernel_dir or Path(tmp)):
            if "board" not in skip:
                rows += board_rows(duration_s)
                rows += hardware_path_rows(duration_s)
                rows += emulation_share_rows(rows)
                rows += emulation_layer_rows(duration_s, rows)
            if "blocks" not in skip:
                rows += block_rows(duration_s)
                rows += seed_fifo_rows(duration_s, rows)
                rows += kernel_break_even_rows()
        return rows


def seed_fifo_rows(duration_s: float, one: list[Row]) -> list[Row]:
    """The seed paraglider vario with its MAX21100 read from the FIFO in blocks of 8 frames
    (the most its driver takes a read), emulated and through the hardware path, against
    the board section's one-frame rows of the same run (``one``)."""
    from tests.benchmarks.bench_blocks import SEED, measure_mode

    fifo = measure_mode(load_registry(), 8, duration_s, 3, SEED)
    x_one = next((r.value for r in one if r.case.startswith("emulated seed board")), None)
    hw_one = next((r.value for r in one if r.case.startswith("hardware path")), None)
    return [
        Row("blocks", f"seed board emulated + estimators, {fifo.label}", fifo.x_real_time,
            "x real time (cpu)", "one frame per block (board row)",
            None if x_one is None else fifo.x_real_time / x_one, ">= 150 x real"),
        Row("blocks", f"seed board hardware path, {fifo.label}", fifo.us_per_imu_sample,
            "us/IMU sample", "one frame per block (board row)",
            None if hw_one is None else fifo.us_per_imu_sample / hw_one, "<= 10"),
        Row("blocks", "  the same without the estimators", fifo.bare_us_per_imu_sample,
            "us/IMU sample"),
    ]


def kernel_break_even_rows() -> list[Row]:
    """The AHRS row kernel against the same frames one by one (issue 24: where a block of
    n frames starts to pay), Madgwick, CPU us per frame, in the same run
    (tests/benchmarks/bench_block_parts.py kernel)."""
    from tests.benchmarks.bench_block_parts import kernel_us_per_frame

    rows = []
    for n, times in kernel_us_per_frame((4, 10, 32, 64)).items():
        forced, one = times["kernel forced"], times["frame by frame"]
        rows.append(Row("blocks", f"madgwick row kernel, fusion steps of {n} frames", forced,
                        "us/frame", "the frames one by one (process())", forced / one))
    return rows


def render(rows: list[Row], markdown: bool) -> str:
    if markdown:
        out = ["| section | case | value | unit | ratio | against | target |",
               "| --- | --- | ---: | --- | ---: | --- | --- |"]
        for r in rows:
            ratio = "" if r.ratio is None else f"{r.ratio:.2f}"
            out.append(f"| {r.section} | {r.case} | {r.value:,.1f} | {r.unit} | {ratio} | "
                       f"{r.peer} | {r.target} |")
        return "\n".join(out)
    out = [f"{'section':<11} {'case':<52} {'value':>12} {'unit':<18} {'ratio':>7}  against"]
    for r in rows:
        ratio = "" if r.ratio is None else f"{r.ratio:.2f}"
        out.append(f"{r.section:<11} {r.case:<52} {r.value:>12,.1f} {r.unit:<18} {ratio:>7}  "
                   f"{r.peer}{'  target ' + r.target if r.target else ''}")
    return "\n".join(out)


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--samples", type=int, default=20_000, help="steps per per-sample case")
    p.add_argument("--rows", type=int, default=200_000,
                   help="rows of the `imuhal estimate` case (the issue's target is 2000000)")
    p.add_argument("--board-s", type=float, default=60.0, help="simulated s of the board case")
    p.add_argument("--kernel-dir", type=Path, help="board and blocks sections: a kernel "
                   "directory `imuhal kernels build` made from these sources (default: build "
                   "one first)")
    p.add_argument("--skip", action="append", default=[],
                   choices=["peers", "estimators", "estimate", "board", "blocks"])
    p.add_argument("--markdown", action="store_true", help="print a Markdown table")
    args = p.parse_args(argv)
    gyro, accel, mag = motion(args.samples)
    rows: list[Row] = []
    if "peers" not in args.skip:
        rows += peer_rows(args.samples, gyro, accel, mag)
    by_case = {r.case: r.value for r in rows}
    vqf_loop = by_case.get("vqf.VQF.update loop 9-DOF")
    vqf_batch = by_case.get("vqf.VQF.updateBatch 9-DOF")
    plain = by_case.get("plain-Python Madgwick 9-DOF loop")
    if "estimators" not in args.skip:
        # the "compiled" rows are numba's JIT even where an extension is built; the AOT
        # extension gets rows of its own, built from the sources as they are now
        os.environ["IMUHAL_KERNELS"] = "jit" if importlib.util.find_spec("numba") else "auto"
        aot_tmp = tempfile.TemporaryDirectory()
        aot_dir: Path | None = Path(aot_tmp.name)
        failed = build_kernels(Path(aot_tmp.name))
        if failed is not None:
            print(f"no AOT batch rows: {failed}", file=sys.stderr)
            aot_dir = None
        est = estimator_rows(args.samples, gyro, accel, mag, vqf_loop, vqf_batch, aot_dir)
        if plain:
            for case in ("madgwick process()", "madgwick process(), aot step"):
                p_us = next((r.value for r in est if r.case == case), None)
                if p_us is not None:
                    est.append(Row("per sample", case, p_us, "us/sample",
                                   "plain-Python Madgwick", p_us / plain))
        rows += est
    if "estimate" not in args.skip:
        upd = next((r.value for r in rows if r.case == "madgwick update()"), None)
        rows += estimate_rows(args.rows, upd)
    if "board" not in args.skip or "blocks" not in args.skip:
        rows += board_and_block_rows(args.board_s, args.skip, args.kernel_dir)
    print(render(rows, args.markdown))
    load = " / ".join(f"{v:.1f}" for v in os.getloadavg())
    print(f"\nCPU time; load average {load} (1 / 5 / 15 min) at the end; "
          f"{sys.version.split()[0]}, numpy {np.__version__}, "
          f"maxrss of this process {resource.getrusage(resource.RUSAGE_SELF).ru_maxrss // 1024}"
          " MB", file=sys.stderr)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
