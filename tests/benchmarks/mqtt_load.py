"""MQTT load: many emulated boards publishing into one broker at once (plain script; not
collected by pytest).

Run:  .venv/bin/python tests/benchmarks/mqtt_load.py [--boards 20] [--duration 60]
      [--decimate PATTERN:N ...]

Starts a mosquitto broker on a loopback port, a paho subscriber to ``imuhal/#`` in this
process, and ``--boards`` ``imuhal run`` processes: the seed GPS vario emulated in real time,
each with its own seed, board name (topic), client id and queue file, decimated to a fleet
telemetry rate (default ``imu/*:50 mag/*:50 ahrs/*:18 baro/*:9 vario/*:9``: about 45 messages
a second per board, attitude at 10 Hz, pressure, temperature and climb at 5 Hz, every GNSS
fix). It
reports the messages per second the subscriber received while every board was running, the
end-to-end latency (the event handed to the sink, ``unix_s``, to its receipt by the
subscriber; one clock), and whether every published message (each run's summary) arrived
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


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--boards", type=int, default=20)
    ap.add_argument("--duration", type=float, default=60.0, help="each run's length, s")
    ap.add_argument("--decimate", action="append", metavar="PATTERN:N",
                    help="the sinks' decimate setting (default imu/*:50 mag/*:50 ahrs/*:18 "
                    "baro/*:9 vario/*:9)")
    args = ap.parse_args()
    decimate = ",".join(args.decimate or ["imu/*:50", "mag/*:50", "ahrs/*:18", "baro/*:9",
                                          "vario/*:9"])
    profile = str(bundled_profiles()["seed-gps-vario.yaml"])
    imuhal = str(Path(sys.executable).with_name("imuhal"))
    with tempfile.TemporaryDirectory(prefix="imuhal-mqtt-load-") as tmp, \
            Mosquitto(Path(tmp) / "broker") as broker:
        sub = Subscriber(broker.port)
        sub.start()
        procs = []
        for i in range(args.boards):
            cmd = [imuhal, "run", profile, "--emulate", "thermal", "--realtime", "--quiet",
                   "--seed", str(i + 1), "--duration", str(args.duration),
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
    print(f"{args.boards} boards (seed GPS vario emulated in real time, {args.duration:.0f} s "
          f"each, decimate {decimate}) into mosquitto on loopback; {os.cpu_count()} CPUs, "
          f"load average {load1:.1f} at the end; processes ran {ended - started:.1f} s")
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
