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
import os
import statistics
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

from tests.support.mqtt_outage import fly_through_outage


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
    with tempfile.TemporaryDirectory(prefix="imuhal-mqtt-outage-") as tmp:
        run = fly_through_outage(Path(tmp), duration_s=args.duration, down_at_s=args.down_at,
                                 outage_s=args.outage, decimate=args.decimate,
                                 queue_max=args.queue_max, receive_timeout_s=120)
    summary, counts, per_topic = run.summary, run.counts, run.per_topic
    backlog = run.backlog()
    drained_s = (max(m.received_unix_s for m in backlog) - run.up_unix_s) if backlog \
        else float("nan")
    live = sorted(m.received_unix_s - m.payload["unix_s"] for v in per_topic.values()
                  for m in v if m.payload["unix_s"] < run.down_unix_s - 1)
    print(f"run {args.duration:.0f} s real time, broker down from {args.down_at:.0f} s for "
          f"{args.outage:.0f} s; mosquitto on loopback; decimate {args.decimate or 'none'}; "
          f"{os.cpu_count()} CPUs, load average {os.getloadavg()[0]:.1f} at the end")
    print(f"pipeline: {summary.simulated_s:.1f} s in {summary.wall_s:.1f} s wall; samples "
          f"{'equal to' if summary.samples == run.expected_samples else 'DIFFERENT FROM'} "
          f"the run without MQTT ({sum(run.expected_samples.values())}); largest gap between "
          f"events handed to the sink {run.largest_gap_s() * 1000:.0f} ms")
    print("sink: " + ", ".join(f"{k.replace('_', ' ')} {v}" for k, v in counts.items()))
    print(f"receiver: {len(run.received)} messages, {len(run.received) - run.kept} "
          f"duplicates dropped by (topic, run, seq), {run.kept} kept of "
          f"{counts['published']} published, {'in order' if run.in_order else 'OUT OF ORDER'}"
          f" on all {len(per_topic)} topics")
    print(f"backlog: the {len(backlog)} messages of the outage all arrived {drained_s:.1f} s "
          f"after the broker came back (drain_rate_msg_s 2000, live messages meanwhile)")
    if live:
        print(f"latency outside the outage (publish to receipt): median "
              f"{statistics.median(live) * 1000:.1f} ms, p99 "
              f"{live[int(0.99 * (len(live) - 1))] * 1000:.1f} ms over {len(live)} messages")
    failures = run.failures()
    for f in failures:
        print(f"FAILED: {f}")
    return 1 if failures else 0


if __name__ == "__main__":
    raise SystemExit(main())
