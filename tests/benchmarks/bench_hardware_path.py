"""What a real board pays per IMU sample: the seed board's drivers, decoding, calibration, mount
rotation and estimators, replayed from a recording of its bus traffic (plain script; not
collected by pytest).

Run:  .venv/bin/python -m tests.benchmarks.bench_hardware_path [--duration 60] [--profile]

A ``--duration`` s emulated run of the seed paraglider vario (profiles/seed-paraglider-vario.yaml,
``thermal``, its estimators) is recorded once (``imuhal run --record``'s recorder); then
``imuhal replay``'s pipeline runs it again with no simulation and no emulator: every bus
transaction and clock reading is answered from the recording, so what is timed is the host's
side of a run, iterated as ``Pipeline.blocks`` (a FIFO read's frames stay in their
blocks, and an AHRS's estimates of them in an AttitudeBlock; nothing in the loop asks for
them one by one). The figure is CPU time per IMU
sample (one gyro + accel burst of the MAX21100, 250 per second; the magnetometer,
barometer and estimators they feed are included).

The records are decoded from the file before the timed replay (decoding is timed on its own,
as the peer: ``imuhal replay`` pays it, real hardware does not); what stays in the figure of
the recording machinery is matching each transaction against the next record, which stands
in for the kernel's SPI transfer on a real board.

``--profile`` prints the replay's cProfile, sorted by own time.

``--recordings DIR`` replays fixed recordings instead, so that two source trees are compared
on the same bytes (run this script with each tree's ``src`` and ``plugins`` first on
``PYTHONPATH``, alternately): the seed board with one frame per block, the seed board with
its MAX21100's FIFO read in blocks of 8 frames and the GY-91 with its MPU-9250's in blocks of
10 (tests/benchmarks/bench_blocks.py's profiles), each ``--duration`` s, recorded into DIR the
first time; each case prints its CPU us per IMU sample, the fastest of ``--repeat`` replays
with the estimators and (in brackets) of as many without, and their medians (``--every``:
every replay's figure). On a loaded machine, run the two trees at the same time rather than
one after the other: side by side they share the load alike.
"""

from __future__ import annotations

import argparse
import cProfile
import os
import pstats
import statistics
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")

from collections.abc import Iterator

from imuhal.bus.base import Bus
from imuhal.bus.recording.format import Record, Recording, open_recording
from imuhal.bus.recording.recorder import BusRecorder, run_header
from imuhal.core.blocks import Block
from imuhal.core.samples import GyroSample
from imuhal.emulation import open_emulated
from imuhal.estimation.outputs import AttitudeBlock
from imuhal.offline.replay import (
    EndOfRecording,
    Replay,
    ReplayClock,
    ReplaySource,
    replay_bus,
    replay_pipeline,
)
from imuhal.plugins.manager import Registry, load_registry
from imuhal.profile.loader import parse_profile

PROFILE = Path(__file__).resolve().parents[2] / "profiles" / "seed-paraglider-vario.yaml"
IMU = "imu"


@dataclass(frozen=True)
class HardwarePath:
    """One measurement: the replay's CPU time, its IMU samples and the peer's CPU time."""

    duration_s: float
    imu_samples: int
    events: int
    replay_cpu_s: float
    decode_cpu_s: float
    bare_cpu_s: float
    """The same replay without the profile's estimators (drivers and pipeline alone)."""

    @property
    def us_per_imu_sample(self) -> float:
        return self.replay_cpu_s / self.imu_samples * 1e6

    @property
    def bare_us_per_imu_sample(self) -> float:
        return self.bare_cpu_s / self.imu_samples * 1e6

    @property
    def decode_us_per_imu_sample(self) -> float:
        return self.decode_cpu_s / self.imu_samples * 1e6


def record(registry: Registry, path: Path, duration_s: float,
           profile_yaml: str | None = None) -> int:
    """Record ``duration_s`` of the emulated seed board (or the board ``profile_yaml``
    describes) to ``path``; returns its events."""
    text = PROFILE.read_text() if profile_yaml is None else profile_yaml
    profile = parse_profile(text, str(PROFILE), registry)
    recorder = BusRecorder(path, run_header(text, str(PROFILE),
                                            emulate=profile.emulation.scenario, seed=None))
    n = 0
    try:
        with open_emulated(profile, registry, recorder=recorder) as pipeline:
            for _ in pipeline.events(duration_s):
                n += 1
    finally:
        recorder.close()
    return n


class DecodedRecording:
    """A recording whose records were decoded beforehand (what ``ReplaySource`` reads)."""

    def __init__(self, recording: Recording, records: list[Record]) -> None:
        self.path = recording.path
        self.version = recording.version
        self.header = recording.header
        self._records = records

    def records(self) -> Iterator[Record]:
        return iter(self._records)


def decoded_replay(path: Path, registry: Registry, *, estimators: bool = True) -> Replay:
    """``open_replay`` of ``path`` with every record decoded first (its own profile;
    ``estimators=False``: without its estimators, which ask nothing of the buses)."""
    recording = open_recording(path)
    decoded = DecodedRecording(recording, list(recording.records()))
    profile = parse_profile(recording.header["profile_yaml"], str(path), registry)
    if not estimators:
        profile = profile.model_copy(update={"estimators": {}})
    source = ReplaySource(decoded)  # type: ignore[arg-type]
    buses: dict[str, Bus] = {info.name: replay_bus(info, source)
                             for info in source.buses.values()}
    return Replay(recording, profile, source, buses, ReplayClock(source))


def replay(registry: Registry, path: Path, *, profiler: cProfile.Profile | None = None,
           estimators: bool = True) -> tuple[int, int, float]:
    """Replay ``path`` (decoded beforehand) to its end: (IMU samples, events, CPU seconds).
    Opening the pipeline (probe and configuration) is not timed."""
    pipeline = replay_pipeline(decoded_replay(path, registry, estimators=estimators),
                               registry)
    imu = events = 0
    t0 = time.process_time()
    if profiler is not None:
        profiler.enable()
    try:
        # Pipeline.blocks: what a consumer that needs no frame one by one iterates (a FIFO
        # read's frames and an AHRS's estimates of them stay arrays); events counts every
        # frame and every estimate
        for item in pipeline.blocks(None):
            if type(item) is Block:
                events += len(item)
                if item.kind is GyroSample and item.device == IMU:
                    imu += len(item)
            elif type(item) is AttitudeBlock:  # an AHRS's estimates of a read, as columns
                events += len(item)
            else:
                events += 1
                if type(item) is GyroSample and item.device == IMU:
                    imu += 1
    except EndOfRecording:
        pass
    finally:
        if profiler is not None:
            profiler.disable()
    return imu, events, time.process_time() - t0


def decode_only(path: Path) -> float:
    """The peer: CPU seconds to decode every record of ``path``."""
    t0 = time.process_time()
    for _ in open_recording(path).records():
        pass
    return time.process_time() - t0


def measure(duration_s: float = 60.0, *, repeat: int = 3, registry: Registry | None = None,
            profile_to: Path | None = None, profile_yaml: str | None = None) -> HardwarePath:
    """Record once, then replay ``repeat`` times and keep the fastest (least disturbed).
    ``profile_yaml``: another board than the seed (its IMU device named ``imu``)."""
    registry = registry or load_registry()
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "seed.imurec"
        record(registry, path, duration_s, profile_yaml)
        best: tuple[int, int, float] | None = None
        for _ in range(max(1, repeat)):
            run = replay(registry, path)
            if best is None or run[2] < best[2]:
                best = run
        assert best is not None
        bare = min(replay(registry, path, estimators=False)[2] for _ in range(max(1, repeat)))
        decode = min(decode_only(path) for _ in range(max(1, repeat)))
        if profile_to is not None:
            prof = cProfile.Profile()
            replay(registry, path, profiler=prof)
            prof.dump_stats(profile_to)
    imu, events, cpu = best
    return HardwarePath(duration_s, imu, events, cpu, decode, bare)


RECORDED_CASES = {"seed": None, "seed-fifo8": 8, "gy91-fifo10": 10}
"""``--recordings``: each case's IMU FIFO block size (None: one frame per block)."""


def recorded_cases(directory: Path, duration_s: float, repeat: int
                   ) -> dict[str, tuple[float, float]]:
    """CPU us per IMU sample of each of RECORDED_CASES replayed from ``directory`` (recorded
    there first when absent), with and without the estimators (the fastest of ``repeat``)."""
    return {case: (min(with_), min(bare)) for case, (with_, bare)
            in recorded_runs(directory, duration_s, repeat).items()}


def recorded_runs(directory: Path, duration_s: float, repeat: int
                  ) -> dict[str, tuple[list[float], list[float]]]:
    """:func:`recorded_cases` with every replay's figure: ``repeat`` replays of each case
    with the estimators, then ``repeat`` without."""
    from tests.benchmarks.bench_blocks import GY91, SEED, board_yaml

    registry = load_registry()
    directory.mkdir(parents=True, exist_ok=True)
    out: dict[str, tuple[list[float], list[float]]] = {}
    for case, frames in RECORDED_CASES.items():
        path = directory / f"{case}-{duration_s:g}s.imurec"
        if not path.exists():
            record(registry, path, duration_s,
                   board_yaml(frames, GY91 if case.startswith("gy91") else SEED))
        runs = [replay(registry, path) for _ in range(max(1, repeat))]
        bare = [replay(registry, path, estimators=False) for _ in range(max(1, repeat))]
        out[case] = ([r[2] / r[0] * 1e6 for r in runs], [r[2] / r[0] * 1e6 for r in bare])
    return out


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--recordings", type=Path, default=None,
                   help="replay fixed recordings kept in this directory (see above)")
    p.add_argument("--duration", type=float, default=60.0, help="recorded simulated s")
    p.add_argument("--repeat", type=int, default=3, help="replays; the fastest counts")
    p.add_argument("--profile", action="store_true", help="print the replay's cProfile")
    p.add_argument("--every", action="store_true",
                   help="--recordings: print every replay's figure too")
    args = p.parse_args(argv)
    if args.recordings is not None:
        for case, (runs, bare) in recorded_runs(args.recordings, args.duration,
                                                args.repeat).items():
            print(f"{case}: {min(runs):.1f} us of CPU per IMU sample ({min(bare):.1f} "
                  f"without the estimators); median {statistics.median(runs):.1f} "
                  f"({statistics.median(bare):.1f})")
            if args.every:
                print(f"  every replay: {' '.join(f'{x:.1f}' for x in runs)} (without the "
                      f"estimators: {' '.join(f'{x:.1f}' for x in bare)})")
        return 0
    with tempfile.TemporaryDirectory() as tmp:
        prof = Path(tmp) / "replay.prof" if args.profile else None
        r = measure(args.duration, repeat=args.repeat, profile_to=prof)
        if prof is not None:
            pstats.Stats(str(prof)).sort_stats("tottime").print_stats(30)
    print(f"seed board replay, {r.duration_s:g} s recorded: {r.imu_samples} IMU samples, "
          f"{r.events} events")
    print(f"hardware path: {r.us_per_imu_sample:.1f} us of CPU per IMU sample "
          f"(target <= 60), {r.bare_us_per_imu_sample:.1f} us of it without the estimators; "
          f"decoding the recording (not included) {r.decode_us_per_imu_sample:.1f} us")
    return 0


if __name__ == "__main__":
    sys.exit(main())
