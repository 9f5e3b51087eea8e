"""The parts of the block path, each against its frame-by-frame peer in one process (plain
script; not collected by pytest). The figures of docs/performance.md, "Blocks reach the
estimators".

Run:  .venv/bin/python -m tests.benchmarks.bench_block_parts PART  (kernel, decode, estimate,
      pipeline, estimates, watchdog, covariance)

- ``kernel``: Madgwick's ``update_blocks`` on fusion steps of n accelerometer and gyro
  frames against the same frames one by one through ``process()`` (the base class's
  ``update_blocks``), CPU us per frame, for n from 1 to 64: where the compiled row kernel
  starts to pay (``MIN_KERNEL_FRAMES`` where the frames one by one run the Python step,
  ``MIN_KERNEL_FRAMES_COMPILED_STEP`` where they run the compiled one: run it with and
  without the AOT extension; below it ``update_blocks`` goes frame by frame).
- ``decode``: the GY-91's MPU-9250 read from its FIFO every 10 periods, a 20 s recording
  replayed without estimators (tests/benchmarks/bench_hardware_path.py), the driver's array
  decoding and the base class's frame-by-frame decoding alternately, CPU us per IMU sample.
- ``estimate``: ``imuhal estimate madgwick``'s work on a generated 200,000-row log, the
  estimates as columns (``attitude_rows``) and as objects through the pipeline's router
  (``fuse_table``), written by the same CSV writer, alternately, CPU s.
- ``pipeline``: the AHRS's row kernel where it runs, in the pipeline: the seed board (its
  MAX21100's FIFO read in blocks of 8 frames, Madgwick with turn compensation by the nominal
  airspeed) and the GY-91 (blocks of 10) replayed from 20 s recordings with the estimators,
  Madgwick taking each read through the row kernel (``MIN_KERNEL_FRAMES_COMPILED_STEP`` 1)
  and frame by frame as shipped (32) alternately, four pairs, CPU us per IMU sample.
- ``estimates``: the hardware path's estimates of a FIFO read, on the seed board (blocks of
  8) and the GY-91 (blocks of 10) replayed from 20 s recordings with the estimators:
  Madgwick's block step handing its estimates on as one AttitudeBlock (vario-kf3 takes it
  whole, no estimate object built: as shipped) against one ``AttitudeEstimate`` per frame
  checked and routed to vario-kf3 one by one (the router's ``estimate_blocks`` off, the
  path before), alternately, four pairs, CPU us per IMU sample.
- ``watchdog``: what timing one driver call costs on CPU time (an emulated or replayed
  board): ``Watchdog.arm`` and ``disarm`` with the ticking timers, against the one-shot
  ``ITIMER_REAL`` and ``ITIMER_PROF`` armed and cancelled around the call (four
  ``setitimer`` calls, the watchdog before), CPU us per call, three rounds.
- ``covariance``: vario-kf3's whole covariance prediction (``Kalman3.predict``, the product
  written out on floats) timed where the seed board's hardware path makes it (FIFO blocks
  of 8, a 20 s recording), against numpy's ``F @ P @ F.T + Q`` alone on the same matrices
  (a BLAS call: the product before), each first on every other call, thread CPU us per
  call, three replays.
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")

import numpy as np

from imuhal.core.blocks import Block
from imuhal.core.samples import AccelSample, Frame, GyroSample
from imuhal.estimation.base import Estimator
from imuhal.plugins.manager import load_registry
from imuhal_filters.common import ahrs


def _block(kind: type, t_ns: np.ndarray, values: np.ndarray) -> Block:
    return Block.from_arrays(kind, "imu", int(t_ns[0]), t_ns - t_ns[0], values,
                             np.zeros(len(t_ns), np.int64), frame=Frame.BODY_NED)


def kernel_us_per_frame(sizes: tuple[int, ...] = (1, 4, 8, 16, 24, 32, 64),
                        frames: int = 4000) -> dict[int, dict[str, float]]:
    """For each step size n: CPU us per frame of Madgwick's ``update_blocks`` as shipped,
    of its compiled kernels (the block step, else the row kernel) forced at any size, and
    of the same frames one by one through ``process()``, one after the other in this
    process."""
    cls = load_registry().estimators.get("madgwick")
    rng = np.random.default_rng(1)
    t = np.arange(frames, dtype=np.int64) * 5_000_000
    g = rng.normal(0, 0.3, (frames, 3))
    a = rng.normal(0, 0.3, (frames, 3)) + np.array([0.0, 0.0, -9.8])

    def steps(n: int) -> list[list[Block]]:
        out = [[_block(AccelSample, t[i:i + n], a[i:i + n]),
                _block(GyroSample, t[i:i + n], g[i:i + n])] for i in range(0, frames, n)]
        for step in out:
            for b in step:
                b.samples()  # the rows exist in both cases (the pipeline's blocks have them)
        return out

    warm = cls()
    for step in steps(64)[:4]:
        warm.update_blocks(step)  # the kernel compiled (JIT) before anything is timed
    shipped = (ahrs.MIN_KERNEL_FRAMES, ahrs.MIN_KERNEL_FRAMES_COMPILED_STEP,
               ahrs.MIN_BLOCK_STEP_FRAMES)
    figures: dict[int, dict[str, float]] = {}
    for n in sizes:
        cases = steps(n)
        times = figures[n] = {}
        for mode in ("update_blocks", "kernel forced", "frame by frame"):
            est = cls()
            est.update_blocks(cases[0])  # aligned
            (ahrs.MIN_KERNEL_FRAMES, ahrs.MIN_KERNEL_FRAMES_COMPILED_STEP,
             ahrs.MIN_BLOCK_STEP_FRAMES) = (1, 1, 1) if mode == "kernel forced" else shipped
            t0 = time.process_time()
            for step in cases[1:]:
                if mode == "frame by frame":
                    Estimator.update_blocks(est, step)
                else:
                    est.update_blocks(step)
            times[mode] = (time.process_time() - t0) / (frames - n) * 1e6
            (ahrs.MIN_KERNEL_FRAMES, ahrs.MIN_KERNEL_FRAMES_COMPILED_STEP,
             ahrs.MIN_BLOCK_STEP_FRAMES) = shipped
    return figures


def kernel() -> None:
    for n, times in kernel_us_per_frame().items():
        print(f"{n:3d} frames a step, us/frame: update_blocks {times['update_blocks']:6.2f}, "
              f"the kernels at any size {times['kernel forced']:6.2f}, frame by frame "
              f"{times['frame by frame']:6.2f}")


def decode(pairs: int = 4) -> None:
    from tests.benchmarks.bench_blocks import gy91_yaml
    from tests.benchmarks.bench_hardware_path import record, replay

    from imuhal.drivers.base import Driver
    from imuhal_chips.mpu9250.driver import MPU9250Driver

    registry = load_registry()
    arrays = MPU9250Driver.poll_blocks
    got: dict[str, list[float]] = {"arrays": [], "frame by frame": []}
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "gy91.imurec"
        record(registry, path, 20.0, gy91_yaml(10))
        try:
            for _ in range(pairs):
                for mode in got:
                    MPU9250Driver.poll_blocks = (  # type: ignore[method-assign]
                        arrays if mode == "arrays" else Driver.poll_blocks)
                    imu, _, cpu = replay(registry, path, estimators=False)
                    got[mode].append(cpu / imu * 1e6)
        finally:
            MPU9250Driver.poll_blocks = arrays  # type: ignore[method-assign]
    for mode, values in got.items():
        print(f"{mode}: {' / '.join(f'{v:.1f}' for v in values)} us per IMU sample "
              "(no estimators)")


def estimate(rows: int = 200_000, pairs: int = 2) -> None:
    from tests.benchmarks.bench_all import write_log

    from imuhal.offline.csv_input import iter_sample_chunks
    from imuhal.offline.csv_output import EstimateCsvWriter
    from imuhal.offline.runner import iter_offline

    cls = load_registry().estimators.get("madgwick")
    with tempfile.TemporaryDirectory() as tmp:
        log = Path(tmp) / "log.csv"
        write_log(log, rows)
        tables = list(iter_sample_chunks(log))
        got: dict[bool, list[float]] = {True: [], False: []}
        for _ in range(pairs):
            for columnar in (True, False):
                est, writer = cls(), EstimateCsvWriter(Path(tmp) / f"out-{columnar}.csv")
                t0 = time.process_time()
                for table in tables:
                    writer.write(next(iter_offline(est, [table], columnar=columnar)))
                writer.commit()
                got[columnar].append(time.process_time() - t0)
        same = ((Path(tmp) / "out-True.csv").read_bytes()
                == (Path(tmp) / "out-False.csv").read_bytes())
    print(f"{rows} rows: columns {' / '.join(f'{v:.2f}' for v in got[True])} s, objects "
          f"through the router {' / '.join(f'{v:.2f}' for v in got[False])} s (CPU); "
          f"same file: {same}")


def pipeline(pairs: int = 4) -> None:
    """The hardware path on FIFO reads with the thresholds as shipped (Madgwick's compiled
    block step from ``MIN_BLOCK_STEP_FRAMES`` frames) against every read frame by frame."""
    from tests.benchmarks.bench_blocks import GY91, SEED, board_yaml
    from tests.benchmarks.bench_hardware_path import record, replay

    registry = load_registry()
    names = ("MIN_BLOCK_STEP_FRAMES", "MIN_KERNEL_FRAMES", "MIN_KERNEL_FRAMES_COMPILED_STEP")
    shipped = {name: getattr(ahrs, name) for name in names}
    never = dict.fromkeys(names, 1 << 30)
    with tempfile.TemporaryDirectory() as tmp:
        for name, board, frames in (("seed board, FIFO 8", SEED, 8),
                                    ("GY-91, FIFO 10", GY91, 10)):
            path = Path(tmp) / f"{frames}.imurec"
            record(registry, path, 20.0, board_yaml(frames, board))
            figures: dict[str, list[float]] = {"shipped": [], "never": []}
            try:
                for _ in range(pairs):
                    for which, limits in (("shipped", shipped), ("never", never)):
                        for key, value in limits.items():
                            setattr(ahrs, key, value)
                        imu, _, cpu = replay(registry, path)
                        figures[which].append(cpu / imu * 1e6)
            finally:
                for key, value in shipped.items():
                    setattr(ahrs, key, value)
            print(f"{name}: us of CPU per IMU sample, the thresholds as shipped "
                  f"{' / '.join(f'{x:.1f}' for x in figures['shipped'])}, frame by frame "
                  f"{' / '.join(f'{x:.1f}' for x in figures['never'])}")


def estimates(pairs: int = 4) -> None:
    """The hardware path on FIFO reads with Madgwick's estimates of a read as one
    AttitudeBlock (as shipped) against one estimate object per frame (before)."""
    from tests.benchmarks.bench_blocks import GY91, SEED, board_yaml
    from tests.benchmarks.bench_hardware_path import record, replay

    from imuhal.pipeline.router import Router

    registry = load_registry()
    shipped = Router.fuse_blocks

    def one_by_one(self: Router, blocks: Any, out: Any, **_: bool) -> None:
        shipped(self, blocks, out, estimate_blocks=False)

    with tempfile.TemporaryDirectory() as tmp:
        for name, board, frames in (("seed board, FIFO 8", SEED, 8),
                                    ("GY-91, FIFO 10", GY91, 10)):
            path = Path(tmp) / f"{frames}.imurec"
            record(registry, path, 20.0, board_yaml(frames, board))
            figures: dict[str, list[float]] = {"blocks": [], "one by one": []}
            try:
                for _ in range(pairs):
                    for which in figures:
                        Router.fuse_blocks = (  # type: ignore[method-assign]
                            shipped if which == "blocks" else one_by_one)
                        imu, _, cpu = replay(registry, path)
                        figures[which].append(cpu / imu * 1e6)
            finally:
                Router.fuse_blocks = shipped  # type: ignore[method-assign]
            print(f"{name}: us of CPU per IMU sample, estimates as AttitudeBlocks "
                  f"{' / '.join(f'{x:.1f}' for x in figures['blocks'])}, one estimate per "
                  f"frame {' / '.join(f'{x:.1f}' for x in figures['one by one'])}; fastest / "
                  f"fastest {min(figures['blocks']) / min(figures['one by one']):.2f}")


def watchdog(calls: int = 100_000, rounds: int = 3) -> None:
    import signal

    from imuhal.pipeline.containment import DriverTiming, Watchdog

    dog = Watchdog(DriverTiming(cpu=True))
    dog.arm(1.0)  # the handlers installed
    dog.disarm()

    def ticking() -> None:
        for _ in range(calls):
            dog.arm(1.0)
            dog.disarm()

    def one_shot() -> None:
        for _ in range(calls):
            signal.setitimer(signal.ITIMER_REAL, 60.0)
            signal.setitimer(signal.ITIMER_PROF, 1.0)
            signal.setitimer(signal.ITIMER_REAL, 0)
            signal.setitimer(signal.ITIMER_PROF, 0)

    try:
        for _ in range(rounds):
            figures = []
            for run in (ticking, one_shot):
                t0 = time.process_time()
                run()
                figures.append((time.process_time() - t0) / calls * 1e6)
            print(f"us of CPU per driver call: ticking timers {figures[0]:.2f}, one-shot "
                  f"timers armed and cancelled {figures[1]:.2f}")
    finally:
        dog.release()


def covariance(rounds: int = 3) -> None:
    """vario-kf3's covariance prediction as the hardware path pays it, once per pressure
    sample between the rest of the path: the whole shipped ``predict`` (the product written
    out on floats) against numpy's ``F @ P @ F.T + Q`` alone (a BLAS call, the product
    before) on the same P, each run first on every other call (the first pays the cold
    caches), thread CPU us per call."""
    from tests.benchmarks.bench_blocks import SEED, board_yaml
    from tests.benchmarks.bench_hardware_path import record, replay

    from imuhal_filters.vario import kf3

    registry = load_registry()
    shipped = kf3.Kalman3.predict
    spent = {"predict": 0, "numpy": 0, "calls": 0}

    def numpy_product(self: Any, dt: float) -> int:
        dt2 = dt * dt
        f = np.array([[1.0, dt, -0.5 * dt2], [0.0, 1.0, -dt], [0.0, 0.0, 1.0]])
        sa2 = self.accel_variance
        q = np.array([[0.25 * dt2 * dt2 * sa2, 0.5 * dt2 * dt * sa2, 0.0],
                      [0.5 * dt2 * dt * sa2, dt2 * sa2, 0.0], [0.0, 0.0, self.bias_variance]])
        p = self.P
        t0 = time.thread_time_ns()
        f @ p @ f.T + q
        return time.thread_time_ns() - t0

    def timed(self: Any, a_meas: float, dt: float) -> None:
        numpy_first = spent["calls"] % 2 == 0
        if numpy_first:
            spent["numpy"] += numpy_product(self, dt)
        t0 = time.thread_time_ns()
        shipped(self, a_meas, dt)
        spent["predict"] += time.thread_time_ns() - t0
        if not numpy_first:
            spent["numpy"] += numpy_product(self, dt)
        spent["calls"] += 1

    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "seed-fifo8.imurec"
        record(registry, path, 20.0, board_yaml(8, SEED))
        kf3.Kalman3.predict = timed  # type: ignore[method-assign]
        try:
            for _ in range(rounds):
                spent.update({"predict": 0, "numpy": 0, "calls": 0})
                imu = replay(registry, path)[0]
                n = spent["calls"]
                print(f"seed board, FIFO 8: {n} predictions ({n / imu:.2f} per IMU sample), "
                      f"thread CPU us per call: the whole predict (written out) "
                      f"{spent['predict'] / n / 1e3:.1f}, numpy's F @ P @ F.T + Q alone "
                      f"{spent['numpy'] / n / 1e3:.1f}")
        finally:
            kf3.Kalman3.predict = shipped  # type: ignore[method-assign]


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("part", choices=["kernel", "decode", "estimate", "pipeline", "estimates",
                                    "watchdog", "covariance"])
    args = p.parse_args(argv)
    {"kernel": kernel, "decode": decode, "estimate": estimate, "pipeline": pipeline,
     "estimates": estimates, "watchdog": watchdog, "covariance": covariance}[args.part]()
    return 0


if __name__ == "__main__":
    sys.exit(main())
