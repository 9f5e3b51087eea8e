"""The pipeline side of the live view: a sink that only remembers the latest state.

``LiveSink.handle`` runs on the pipeline's thread for every event, so it does the least it
can: under one short lock it stores the event as the latest of its kind, counts it, and (for
a body-frame gyro) adds its rate times the interval to a running rotation, for the bring-up
checks. It never waits for anything else: the publisher thread (imuhal.live.server) copies
the state at the display rate, and browsers only ever see those copies.
"""

from __future__ import annotations

import threading
import time
from collections import Counter
from dataclasses import dataclass, field

from imuhal.core.samples import Frame, Quantity, Sample, SampleFlag
from imuhal.estimation.outputs import AttitudeEstimate, VerticalEstimate
from imuhal.sinks.base import Event

_GYRO = Quantity.GYRO
_BODY_NED = Frame.BODY_NED  # module constants: an enum member looked up per event costs


@dataclass
class DeviceState:
    """What the live view knows about one device: latest sample per channel (valid or not),
    latest valid one, counts, flags by kind, and its integrated body rotation (rad)."""

    latest: dict[Quantity, Sample] = field(default_factory=dict)
    latest_valid: dict[Quantity, Sample] = field(default_factory=dict)
    counts: dict[Quantity, int] = field(default_factory=dict)
    flagged: Counter[str] = field(default_factory=Counter)
    rotation_rad: list[float] = field(default_factory=lambda: [0.0, 0.0, 0.0])
    last_gyro_ns: int | None = None
    last_t_ns: int | None = None


@dataclass
class Copy:
    """A consistent copy of the sink's state, taken by :meth:`LiveSink.copy`."""

    t_ns: int | None
    events: int
    closed: bool
    devices: dict[str, DeviceState]
    attitudes: dict[str, AttitudeEstimate]
    verticals: dict[str, VerticalEstimate]
    first_wall_s: float | None = None
    """The wall clock (time.monotonic) at the run's first event and at its end: the wall
    time of the run's summary."""
    closed_wall_s: float | None = None


class LiveSink:
    """Keeps the latest sample of every device and channel and the latest estimate of every
    estimator; never blocks the pipeline (the lock is held for a few dict updates)."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._devices: dict[str, DeviceState] = {}
        self._attitudes: dict[str, AttitudeEstimate] = {}
        self._verticals: dict[str, VerticalEstimate] = {}
        self._t_ns: int | None = None
        self._first_wall_s: float | None = None
        self._closed_wall_s: float | None = None
        self._events = 0
        self.closed = False

    def handle(self, event: Event) -> None:
        # Runs for every event on the pipeline's thread: keep it to a few dict operations.
        with self._lock:
            self._events += 1
            self._t_ns = event.t_ns
            if self.closed or self._first_wall_s is None:
                # the first event, or one after close: the same view watches a new run
                self.closed = False
                self._first_wall_s = time.monotonic()
            if isinstance(event, Sample):
                self._sample(event)
            elif isinstance(event, AttitudeEstimate):
                self._attitudes[event.source] = event
            elif isinstance(event, VerticalEstimate):
                self._verticals[event.source] = event
            # other estimate types: nothing on the page shows them yet

    def _sample(self, sample: Sample) -> None:
        dev = self._devices.get(sample.device)
        if dev is None:
            dev = self._devices[sample.device] = DeviceState()
        channel = sample.channel
        dev.latest[channel] = sample
        counts = dev.counts
        counts[channel] = counts.get(channel, 0) + 1
        dev.last_t_ns = sample.t_ns
        if sample.flags:
            for flag in SampleFlag:
                if flag and flag in sample.flags:
                    dev.flagged[flag.name or str(int(flag))] += 1
            return
        dev.latest_valid[channel] = sample
        if channel is _GYRO and sample.frame is _BODY_NED:  # type: ignore[attr-defined]
            last = dev.last_gyro_ns
            if last is not None and sample.t_ns > last:
                dt = (sample.t_ns - last) * 1e-9
                w = sample.gyro_rad_s  # type: ignore[attr-defined]
                r = dev.rotation_rad
                r[0] += w[0] * dt
                r[1] += w[1] * dt
                r[2] += w[2] * dt
            dev.last_gyro_ns = sample.t_ns

    def copy(self) -> Copy:
        """The state now, copied under the lock (shallow: samples and estimates are frozen)."""
        with self._lock:
            devices = {
                name: DeviceState(latest=dict(d.latest), latest_valid=dict(d.latest_valid),
                                  counts=dict(d.counts), flagged=Counter(d.flagged),
                                  rotation_rad=list(d.rotation_rad),
                                  last_gyro_ns=d.last_gyro_ns, last_t_ns=d.last_t_ns)
                for name, d in self._devices.items()}
            return Copy(t_ns=self._t_ns, events=self._events,
                        closed=self.closed, devices=devices,
                        attitudes=dict(self._attitudes), verticals=dict(self._verticals),
                        first_wall_s=self._first_wall_s,
                        closed_wall_s=self._closed_wall_s)

    def close(self) -> None:
        """The run ended (the page says so); the server keeps serving the last state."""
        with self._lock:
            self.closed = True
            self._closed_wall_s = time.monotonic()
