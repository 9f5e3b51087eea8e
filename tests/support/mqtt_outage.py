"""A broker outage in the middle of a real-time run: the seed GPS vario, emulated and paced
in real time, publishes through the MQTT sink to a real mosquitto that is stopped
``down_at_s`` into the run and started again ``outage_s`` later, while a persistent-session
subscriber records every message. Shared by the suite's short outage test, its long
(300 s, 60 s down) version and the benchmark script that reports the figures
(tests/benchmarks/mqtt_outage.py)."""

from __future__ import annotations

import threading
import time
from dataclasses import dataclass
from itertools import pairwise
from pathlib import Path
from typing import Any

from tests.support.mosquitto import Mosquitto, Received, Subscriber, deduplicated

from imuhal.emulation import open_emulated
from imuhal.plugins.manager import load_registry
from imuhal.profile.bundled import bundled_profiles
from imuhal.profile.loader import load_profile
from imuhal.sinks.mqtt import MqttSink

BOARD = "seed-gps-vario"


@dataclass
class Outage:
    """What one run through an outage did, and what the subscriber received."""

    duration_s: float
    down_at_s: float
    outage_s: float
    queue_max: int
    expected_samples: dict[str, int]
    """The same seeded run's sample counts without MQTT."""
    summary: Any
    """The run's RunSummary."""
    received: list[Received]
    """Every message the subscriber got, duplicates included, in arrival order."""
    t0_unix_s: float
    up_unix_s: float
    """When the broker was listening again (NaN: it never came back)."""

    @property
    def counts(self) -> dict[str, int]:
        """The sink's closing counts (published, sent, queued, dropped, queue_peak, ...)."""
        return dict(self.summary.sinks["mqtt"])

    @property
    def per_topic(self) -> dict[str, list[Received]]:
        """What a receiver keeps after de-duplication by (topic, run, seq)."""
        return deduplicated(self.received)

    @property
    def kept(self) -> int:
        return sum(len(v) for v in self.per_topic.values())

    @property
    def in_order(self) -> bool:
        """Every stream's kept messages are its sequence numbers 0, 1, 2, ... (none missing,
        none out of order)."""
        return all([m.payload["seq"] for m in v] == list(range(len(v)))
                   for v in self.per_topic.values())

    @property
    def down_unix_s(self) -> float:
        return self.t0_unix_s + self.down_at_s

    def imu_stamps(self) -> list[float]:
        """When each accelerometer sample was handed to the sink (its ``unix_s``)."""
        return [m.payload["unix_s"] for m in self.per_topic.get(f"imuhal/{BOARD}/imu/accel", [])]

    def largest_gap_s(self) -> float:
        """The longest wait between two accelerometer samples handed to the sink: a pipeline
        waiting for the network would leave a gap as long as the outage."""
        return max((b - a for a, b in pairwise(self.imu_stamps())), default=float("nan"))

    @property
    def pause_bound_s(self) -> float:
        """The longest pause allowed between two samples handed to the sink: half the
        outage, at most 2 s (a loaded machine pauses the whole process for a fraction of a
        second now and then; a pipeline waiting for the broker would pause for the whole
        outage)."""
        return min(self.outage_s / 2, 2.0)

    def backlog(self) -> list[Received]:
        """The messages handed to the sink while the broker was down."""
        return [m for v in self.per_topic.values() for m in v
                if self.down_unix_s <= m.payload["unix_s"] < self.up_unix_s]

    def failures(self) -> list[str]:
        """Each broken promise of docs/outputs.md, in one line; empty when all held."""
        counts, out = self.counts, []
        if self.summary.samples != self.expected_samples:
            out.append("the samples differ from the same run without MQTT")
        if self.kept != counts["published"] or not self.in_order:
            out.append(f"{self.kept} of {counts['published']} messages kept after "
                       f"de-duplication, {'in' if self.in_order else 'NOT in'} order")
        if counts["dropped"] or counts["dropped_handoff"] or counts["left"]:
            out.append("messages were dropped or left in the queue")
        if counts["queue_peak"] > self.queue_max:
            out.append(f"the queue held {counts['queue_peak']} > {self.queue_max} messages")
        if not counts["queued"] or not counts["reconnects"]:
            out.append("the sink never queued or reconnected: the outage missed the run")
        if not self.largest_gap_s() < self.pause_bound_s:
            out.append(f"the pipeline paused {self.largest_gap_s():.1f} s")
        return out


def fly_through_outage(folder: Path, *, duration_s: float, down_at_s: float, outage_s: float,
                       decimate: list[str], queue_max: int,
                       receive_timeout_s: float = 60.0) -> Outage:
    """One run of ``duration_s`` (real time) through an outage of ``outage_s`` starting at
    ``down_at_s``, with its broker, subscriber and queue file in ``folder``."""
    registry = load_registry()
    profile = load_profile(bundled_profiles()["seed-gps-vario.yaml"], registry)
    with open_emulated(profile, registry, scenario="thermal") as reference:
        expected = reference.run(duration_s).samples
    with Mosquitto(folder / "broker") as broker:
        sub = Subscriber(broker.port)
        sub.start()
        try:
            sink = MqttSink({"url": broker.url, "board": BOARD, "decimate": decimate,
                             "queue_path": str(folder / "queue.sqlite"),
                             "queue_max_messages": queue_max, "close_timeout_s": 120})
            up: list[float] = []

            def back_up() -> None:
                broker.start()
                up.append(time.time())

            timers = [threading.Timer(down_at_s, broker.stop),
                      threading.Timer(down_at_s + outage_s, back_up)]
            with open_emulated(profile, registry, scenario="thermal",
                               realtime=True) as pipeline:
                t0_unix = time.time()  # the outage's clock starts with the run
                for t in timers:
                    t.start()
                summary = pipeline.run(duration_s, [sink])
            for t in timers:
                t.join()
            sub.wait_for(summary.sinks["mqtt"]["published"], timeout_s=receive_timeout_s)
            time.sleep(1.0)  # a duplicate still on its way is counted too
            received = sub.wait_for(0)
        finally:
            sub.stop()
    return Outage(duration_s, down_at_s, outage_s, queue_max, expected, summary, received,
                  t0_unix, up[0] if up else float("nan"))
