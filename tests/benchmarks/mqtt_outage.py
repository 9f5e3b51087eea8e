"""MQTT store-and-forward through a broker outage, the issue's full figure (plain script; not
collected by pytest; the suite's short version is tests/sinks/test_mqtt_broker.py).

Run:  .venv/bin/python tests/benchmarks/mqtt_outage.py [--duration 300] [--down-at 120]
      [--outage 60] [--decimate PATTERN:N ...]

The seed GPS vario (profiles/seed-gps-vario.yaml), emulated and paced in real time, publishes
its events at a telemetry rate (default decimation ``imu/*:10 mag/*:10 ahrs/*:4``: about 200
messages a second of its 950 events; ``--decimate '*:1'`` publishes every event) to a real
mosquitto broker on a loopback port,
started by this script with persistent sessions; a paho subscriber with a persistent session
records every message. The broker is stopped (SIGTERM) ``--down-at`` seconds into the run
and started again ``--outage`` seconds later. The script then checks and reports:

* **delivery**: after de-duplication by (topic, run, seq) (docs/outputs.md), every published
  message arrived exactly once and in order per stream, with how many duplicates came;
* **pace**: the run's sample counts equal those of the same run without MQTT (no sample lost)
  and the largest gap between two events handed to the sink (``unix_s`` of the IMU stream:
  a pipeline waiting for the network would leave a gap as long as the outage);
* **queue**: its largest length against its bound, messages queued and dropped, the
  reconnections, how long the backlog took to drain after the broker came back;
* **latency**: publish (``unix_s``) to receipt, median and 99th percentile, outside the
  outage and backlog.

Exit 1 when a check fails.
"""

from __future__ import annotations

import argparse
import statistics
import sys
import tempfile
import threading
import time
from itertools import pairwise
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

from tests.support.mosquitto import Mosquitto, Subscriber, deduplicated

from imuhal.emulation import open_emulated
from imuhal.plugins.manager import load_registry
from imuhal.profile.bundled import bundled_profiles
from imuhal.profile.loader import load_profile
from imuhal.sinks.mqtt import MqttSink

BOARD = "seed-gps-vario"


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--duration", type=float, default=300.0, help="run length, s")
    ap.add_argument("--down-at", type=float, default=120.0, help="broker stopped at, s")
    ap.add_argument("--outage", type=float, default=60.0, help="broker down for, s")
    ap.add_argument("--decimate", action="append", metavar="PATTERN:N",
                    help="the sink's decimate setting (default imu/*:10 mag/*:10 ahrs/*:4)")
    ap.add_argument("--queue-max", type=int, default=200_000, help="queue_max_messages")
    args = ap.parse_args()
    args.decimate = args.decimate or ["imu/*:10", "mag/*:10", "ahrs/*:4"]
    registry = load_registry()
    profile = load_profile(bundled_profiles()["seed-gps-vario.yaml"], registry)
    with open_emulated(profile, registry, scenario="thermal") as reference:
        expected = reference.run(args.duration).samples
    failures: list[str] = []
    with tempfile.TemporaryDirectory(prefix="imuhal-mqtt-outage-") as tmp, \
            Mosquitto(Path(tmp) / "broker") as broker:
        sub = Subscriber(broker.port)
        sub.start()
        sink = MqttSink({"url": broker.url, "board": BOARD, "decimate": args.decimate,
                         "queue_path": str(Path(tmp) / "queue.sqlite"),
                         "queue_max_messages": args.queue_max, "close_timeout_s": 120})
        t0_unix = time.time()
        up_unix: list[float] = []

        def back_up() -> None:
            broker.start()
            up_unix.append(time.time())

        timers = [threading.Timer(args.down_at, broker.stop),
                  threading.Timer(args.down_at + args.outage, back_up)]
        with open_emulated(profile, registry, scenario="thermal", realtime=True) as pipeline:
            for t in timers:
                t.start()
            summary = pipeline.run(args.duration, [sink])
        for t in timers:
            t.join()
        counts = summary.sinks["mqtt"]
        got = sub.wait_for(counts["published"], timeout_s=120)
        time.sleep(2.0)  # duplicates still on their way
        got = list(sub.messages)
        sub.stop()
    per_topic = deduplicated(got)
    kept = sum(len(v) for v in per_topic.values())
    in_order = all([m.payload["seq"] for m in v] == list(range(len(v)))
                   for v in per_topic.values())
    imu = per_topic.get(f"imuhal/{BOARD}/imu/accel", [])
    stamps = [m.payload["unix_s"] for m in imu]
    gap = max((b - a for a, b in pairwise(stamps)), default=float("nan"))
    down_unix = t0_unix + args.down_at
    up = up_unix[0] if up_unix else float("nan")
    # the backlog: events handed to the sink while the broker was down; drained when the last
    # of them arrived (they arrive in order, interleaved with the live messages)
    backlog = [m for v in per_topic.values() for m in v if down_unix <= m.payload["unix_s"] < up]
    drained_s = (max(m.received_unix_s for m in backlog) - up) if backlog else float("nan")
    live = [m.received_unix_s - m.payload["unix_s"] for v in per_topic.values() for m in v
            if m.payload["unix_s"] < down_unix - 1]
    live.sort()

    print(f"run {args.duration:.0f} s real time, broker down from {args.down_at:.0f} s for "
          f"{args.outage:.0f} s; mosquitto on loopback; decimate {args.decimate or 'none'}")
    print(f"pipeline: {summary.simulated_s:.1f} s in {summary.wall_s:.1f} s wall; samples "
          f"{'equal to' if summary.samples == expected else 'DIFFERENT FROM'} the run "
          f"without MQTT ({sum(expected.values())}); largest gap between events handed to "
          f"the sink {gap * 1000:.0f} ms")
    print("sink: " + ", ".join(f"{k.replace('_', ' ')} {v}" for k, v in counts.items()))
    print(f"receiver: {len(got)} messages, {len(got) - kept} duplicates dropped by "
          f"(topic, run, seq), {kept} kept of {counts['published']} published, "
          f"{'in order' if in_order else 'OUT OF ORDER'} on all {len(per_topic)} topics")
    print(f"backlog: the {len(backlog)} messages of the outage all arrived {drained_s:.1f} s "
          f"after the broker came back (drain_rate_msg_s 2000, live messages meanwhile)")
    if live:
        print(f"latency outside the outage (publish to receipt): median "
              f"{statistics.median(live) * 1000:.1f} ms, p99 "
              f"{live[int(0.99 * (len(live) - 1))] * 1000:.1f} ms over {len(live)} messages")
    if summary.samples != expected:
        failures.append("samples differ from the run without MQTT")
    if kept != counts["published"] or not in_order:
        failures.append("not every message arrived once and in order")
    if counts["dropped"] or counts["dropped_handoff"] or counts["left"]:
        failures.append("messages were dropped or left")
    if counts["queue_peak"] > args.queue_max:
        failures.append("the queue exceeded its bound")
    if not gap < 1.0:
        failures.append(f"the pipeline paused {gap:.1f} s")
    for f in failures:
        print(f"FAILED: {f}")
    return 1 if failures else 0


if __name__ == "__main__":
    raise SystemExit(main())
