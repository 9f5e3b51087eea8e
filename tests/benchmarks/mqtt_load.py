"""MQTT load: many recorded boards replayed into one broker at once (plain script; not
collected by pytest).

Run:  nice -n 10 .venv/bin/python tests/benchmarks/mqtt_load.py [--boards 20] [--duration 60]
      [--recordings DIR] [--decimate PATTERN:N ...]

First it records ``--boards`` flights (``imuhal run --record``: the seed GPS vario emulated
flying ``thermal``, each with its own seed, two at a time, not paced) into ``--recordings``
(kept, and reused when they are already there), or a temporary folder. Then it starts a
mosquitto broker on a loopback port, a paho subscriber to ``imuhal/#`` in this process, and
one ``imuhal replay --realtime --mqtt`` process per recording at once: each replays its
board's recorded bus transactions through the drivers and estimators at the recorded pace,
with its own board name (topic), client id and queue file, decimated to a fleet telemetry
rate (default ``imu/*:50 mag/*:50 ahrs/*:18 baro/*:9 vario/*:9``: about 45 messages a second
per board, attitude at 10 Hz, pressure, temperature and climb at 5 Hz, every GNSS fix). It
reports the messages per second the subscriber received while every board was running, the
end-to-end latency (the event handed to the sink, ``unix_s``, to its receipt by the
subscriber; one clock), and whether every published message (each replay's summary) arrived
exactly once and in order per stream. Exit 1 when one did not.
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

from tests.support.mosquitto import Mosquitto, Subscriber, deduplicated

from imuhal.profile.bundled import bundled_profiles


def _published(stderr: str) -> int:
    line = next(x for x in stderr.splitlines() if x.strip().startswith("mqtt: published"))
    return int(line.split("published", 1)[1].split(",", 1)[0])


def record(folder: Path, boards: int, duration_s: float) -> list[Path]:
    """One recording per board (seeds 1..boards), made two at a time; existing ones kept."""
    profile = str(bundled_profiles()["seed-gps-vario.yaml"])
    imuhal = str(Path(sys.executable).with_name("imuhal"))
    folder.mkdir(parents=True, exist_ok=True)
    paths = [folder / f"board-{i:02d}.imurec" for i in range(boards)]
    todo = [(i, p) for i, p in enumerate(paths) if not p.exists()]
    for start in range(0, len(todo), 2):
        procs = [subprocess.Popen([imuhal, "run", profile, "--emulate", "thermal", "--quiet",
                                   "--skip-calibration", "--seed", str(i + 1), "--duration",
                                   str(duration_s), "--record", str(p)],
                                  stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
                 for i, p in todo[start:start + 2]]
        for proc in procs:
            err = proc.communicate()[1]
            if proc.returncode != 0:
                raise SystemExit(f"recording failed: {err.strip().splitlines()[-1:]}")
    return paths


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--boards", type=int, default=20)
    ap.add_argument("--duration", type=float, default=60.0, help="each recording's length, s")
    ap.add_argument("--recordings", type=Path, metavar="DIR",
                    help="where the recordings are made, or found (default: a temporary folder)")
    ap.add_argument("--decimate", action="append", metavar="PATTERN:N",
                    help="the sinks' decimate setting (default imu/*:50 mag/*:50 ahrs/*:18 "
                    "baro/*:9 vario/*:9)")
    args = ap.parse_args()
    decimate = ",".join(args.decimate or ["imu/*:50", "mag/*:50", "ahrs/*:18", "baro/*:9",
                                          "vario/*:9"])
    imuhal = str(Path(sys.executable).with_name("imuhal"))
    with tempfile.TemporaryDirectory(prefix="imuhal-mqtt-load-") as tmp:
        recordings = record(args.recordings or Path(tmp) / "recordings", args.boards,
                            args.duration)
        with Mosquitto(Path(tmp) / "broker") as broker:
            sub = Subscriber(broker.port)
            sub.start()
            procs = []
            for i, recording in enumerate(recordings):
                cmd = [imuhal, "replay", str(recording), "--realtime", "--quiet",
                       "--mqtt", broker.url, "--sink-set", f"mqtt.board=board-{i:02d}",
                       "--sink-set", f"mqtt.queue_path={tmp}/queue-{i:02d}.sqlite",
                       "--sink-set", f"mqtt.decimate={decimate}"]
                procs.append(subprocess.Popen(cmd, stdout=subprocess.DEVNULL,
                                              stderr=subprocess.PIPE, text=True))
            started = time.time()
            errs = [p.communicate()[1] for p in procs]
            ended = time.time()
            failed = [i for i, p in enumerate(procs) if p.returncode != 0]
            published = sum(_published(e) for i, e in enumerate(errs) if i not in failed)
            got = sub.wait_for(published, timeout_s=120)
            sub.stop()
    load1, _, _ = os.getloadavg()
    per_topic = deduplicated(got)
    kept = sum(len(v) for v in per_topic.values())
    in_order = all([m.payload["seq"] for m in v] == list(range(len(v)))
                   for v in per_topic.values())
    # the steady window: every board running (the last one started, none finished)
    first_each = {}
    last_each = {}
    for m in got:
        board = m.topic.split("/")[1]
        first_each.setdefault(board, m.payload["unix_s"])
        last_each[board] = m.payload["unix_s"]
    w0, w1 = max(first_each.values()), min(last_each.values())
    window = [m for m in got if w0 <= m.received_unix_s <= w1]
    rate = len(window) / (w1 - w0) if w1 > w0 else float("nan")
    latency = sorted(m.received_unix_s - m.payload["unix_s"] for m in window)
    print(f"{args.boards} recorded boards (seed GPS vario, thermal, {args.duration:.0f} s "
          f"each) replayed at once in real time, decimate {decimate}, into mosquitto on "
          f"loopback; {os.cpu_count()} CPUs, load average {load1:.1f} at the end; replays "
          f"ran {ended - started:.1f} s")
    print(f"received {len(got)} messages ({len(got) - kept} duplicates) of {published} "
          f"published; {'all' if kept == published else 'NOT all'} once, "
          f"{'in order' if in_order else 'OUT OF ORDER'} on {len(per_topic)} topics; "
          f"{len(failed)} runs failed")
    if latency:
        print(f"while all {args.boards} ran ({w1 - w0:.1f} s): {rate:.0f} messages/s; latency "
              f"median {statistics.median(latency) * 1000:.1f} ms, p99 "
              f"{latency[int(0.99 * (len(latency) - 1))] * 1000:.1f} ms, max "
              f"{latency[-1] * 1000:.1f} ms")
    for i in failed:
        print(f"board {i:02d} failed: {errs[i].strip().splitlines()[-1:]}")
    return 0 if kept == published and in_order and not failed else 1


if __name__ == "__main__":
    raise SystemExit(main())
