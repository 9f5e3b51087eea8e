"""The MQTT sink: every event (streams and decimation chosen in the settings) as a QoS 1
message on ``<prefix>/<board>/<source>/<kind>``, surviving a broker outage.

Threads (the pipeline never waits for the network or the disk):

* the **pipeline thread** (:meth:`MqttSink.handle`) encodes the event and appends it to a
  bounded in-memory hand-off (a deque; when full, its oldest message is dropped and counted
  in ``dropped_handoff``);
* the **publisher thread** moves the hand-off into the on-disk queue (queue.py: bounded by
  count and age, oldest dropped first and counted), hands queued messages to paho in order,
  at most ``drain_rate_msg_s`` a second and ``inflight_max`` unacknowledged at once, and
  deletes each from the queue when the broker acknowledges it (PUBACK);
* **paho's network thread** connects, reconnects (backing off up to ``reconnect_max_s``) and
  re-sends the unacknowledged messages after a reconnect.

Delivery is at least once, in order per topic: a message the broker received but whose PUBACK
was lost is sent again. Each payload carries ``run`` (the run's start, UNIX ms) and ``seq``
(per stream, from 0, after decimation), so a receiver drops a duplicate by keeping, per topic
and run, the highest ``seq`` seen and discarding messages at or below it; a gap in ``seq``
is a message dropped by a queue limit (the run summary counts them).
"""

from __future__ import annotations

import contextlib
import hashlib
import os
import socket
import sys
import threading
import time
from collections import deque
from collections.abc import Mapping
from pathlib import Path
from typing import Any, ClassVar

from pydantic import BaseModel, ConfigDict, Field, SecretStr, field_validator

from imuhal.core.conventions import convention_name, get_convention
from imuhal.core.errors import ImuhalError
from imuhal.sinks.base import Event, SinkPlugin
from imuhal.sinks.builtin import event_row
from imuhal.sinks.mqtt.broker import Broker, parse_broker_url
from imuhal.sinks.mqtt.payload import StreamSelector, encode, stream_of, topic_level
from imuhal.sinks.mqtt.queue import DiskQueue


class MqttSettings(BaseModel):
    """Settings of the ``mqtt`` sink (profile ``outputs.mqtt``, ``--sink-set mqtt.KEY=VALUE``;
    ``--mqtt URL`` sets ``url``). ``board`` and ``frame`` default to the run's profile name and
    output frame."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    url: SecretStr | None = None
    """``mqtt://[USER[:PASSWORD]@]HOST[:PORT]`` or ``mqtts://`` (TLS); credentials may
    instead come from IMUHAL_MQTT_USERNAME / IMUHAL_MQTT_PASSWORD. Never printed."""
    board: str = "board"
    """The topic level naming this board: give each board of a fleet its own."""
    topic_prefix: str = "imuhal"
    frame: str = "ned"
    """Convention of the payload's frame-dependent columns (docs/units-and-frames.md)."""
    client_id: str | None = None
    """MQTT client id; default ``imuhal-<board>-<8 hex digits of the host name>``, the same
    on every run of this board on this machine."""
    streams: tuple[str, ...] = ("*",)
    """Streams published (fnmatch patterns of ``source/kind``: ``ahrs/*``, ``*/pressure``)."""
    decimate: dict[str, int] = Field(default_factory=dict)
    """Pattern -> N: publish every Nth event of the matching streams (first match wins); on
    the command line ``--sink-set mqtt.decimate=imu/*:10,mag/*:5``."""
    queue_path: str | None = None
    """The on-disk queue (SQLite); default ``$XDG_STATE_HOME/imuhal/mqtt/<client id>.sqlite``
    (``~/.local/state/...``)."""
    queue_max_messages: int = Field(200_000, ge=1)
    """At most this many messages wait on disk; beyond it the oldest are dropped (counted)."""
    queue_max_age_s: float = Field(24 * 3600.0, gt=0)
    """Messages waiting longer than this (wall-clock seconds) are dropped (counted)."""
    drain_rate_msg_s: float = Field(2000.0, gt=0)
    """Most messages a second handed to the broker (a backlog drains at this rate; it must
    exceed the live rate for a backlog to shrink)."""
    inflight_max: int = Field(100, ge=1, le=10_000)
    """Most messages sent and not yet acknowledged."""
    handoff_max: int = Field(100_000, ge=1)
    """Most messages between the pipeline thread and the publisher thread (memory)."""
    keepalive_s: int = Field(15, ge=5, le=3600)
    reconnect_max_s: int = Field(4, ge=1, le=600)
    """Longest wait between two connection attempts (the wait doubles from 1 s)."""
    close_timeout_s: float = Field(10.0, ge=0)
    """At the end of a run, how long to keep sending the queue before leaving the rest in
    the file for the next run."""
    tls_ca_file: str | None = None
    """CA certificates (PEM) for mqtts://; default: the system's."""

    @field_validator("streams", mode="before")
    @classmethod
    def _one_pattern(cls, value: Any) -> Any:
        return (value,) if isinstance(value, str) else value

    @field_validator("decimate", mode="before")
    @classmethod
    def _pattern_list(cls, value: Any) -> Any:
        """``"imu/*:10"`` or a list of them (the command line) -> ``{"imu/*": 10}``."""
        if isinstance(value, str):
            value = [value]
        if isinstance(value, list | tuple):
            out: dict[str, int] = {}
            for item in value:
                pattern, sep, n = str(item).rpartition(":")
                if not sep or not pattern or not n.strip().isdigit():
                    raise ValueError(f"{item!r}: write PATTERN:N, e.g. imu/*:10")
                out[pattern] = int(n)
            return out
        return value

    @field_validator("decimate")
    @classmethod
    def _positive(cls, value: dict[str, int]) -> dict[str, int]:
        bad = [p for p, n in value.items() if n < 1]
        if bad:
            raise ValueError(f"decimate {bad[0]!r}: N must be 1 or more (1 = every event)")
        return value

    _frame = field_validator("frame")(convention_name)


def default_client_id(board: str) -> str:
    """``imuhal-<board>-<8 hex>``: stable for this board on this host, distinct between
    hosts that run boards of the same name."""
    host = hashlib.sha256(socket.gethostname().encode()).hexdigest()[:8]
    return f"imuhal-{topic_level(board)}-{host}"


def default_queue_path(client_id: str) -> Path:
    state = os.environ.get("XDG_STATE_HOME") or os.path.join(Path.home(), ".local", "state")
    return Path(state) / "imuhal" / "mqtt" / f"{client_id}.sqlite"


COUNTERS = ("published", "sent", "queued", "dropped", "dropped_handoff", "reconnects",
            "queue_peak", "left")
"""The run summary's MQTT counts: events published by the pipeline (after decimation);
acknowledged by the broker; stored while the broker was unreachable; dropped by the queue's
limits (oldest first); dropped because the hand-off to the publisher thread was full;
reconnections after a lost connection; the queue's largest length; left in the queue file
at the end (sent by the next run)."""


class MqttSink(SinkPlugin):
    """Publishes the run's events to an MQTT broker with an on-disk store-and-forward queue
    (module docstring; docs/outputs.md, "MQTT")."""

    name: ClassVar[str] = "mqtt"
    description: ClassVar[str] = ("events as compact JSON on imuhal/<board>/<stream> over MQTT "
                                  "(QoS 1), queued on disk while the broker is unreachable")
    Settings = MqttSettings

    def __init__(self, settings: MqttSettings | Mapping[str, Any] | None = None, *,
                 env: Mapping[str, str] | None = None) -> None:
        super().__init__(settings)
        s: MqttSettings = self.settings  # type: ignore[assignment]  # the plugin's own Settings model: the base class types settings as the base model
        if s.url is None:
            raise ImuhalError("the mqtt sink has no broker URL: add --mqtt mqtt://HOST[:PORT] "
                              "(or url in the profile's outputs.mqtt)")
        self.broker: Broker = parse_broker_url(s.url.get_secret_value(),
                                               os.environ if env is None else env)
        mqtt = _paho()
        self.frame = get_convention(s.frame)
        self.client_id = s.client_id or default_client_id(s.board)
        self._topic_root = f"{s.topic_prefix}/{topic_level(s.board)}/"
        self.queue = DiskQueue(s.queue_path or default_queue_path(self.client_id),
                               max_messages=s.queue_max_messages, max_age_s=s.queue_max_age_s)
        self.run_id = int(time.time() * 1000)
        """The run's start, UNIX milliseconds: with ``seq``, a message's identity."""
        self.counts = dict.fromkeys(COUNTERS, 0)
        self.counts["queue_peak"] = len(self.queue)
        self.last_error: str | None = None
        self.failure: str | None = None
        """Why the publisher thread stopped before the end of the run (None: it did not)."""
        self._selector = StreamSelector(s.streams, s.decimate)
        self._seq: dict[str, int] = {}
        self._handoff: deque[tuple[str, bytes, float]] = deque()
        self._wake = threading.Event()
        self._stop = threading.Event()
        self._connected = threading.Event()
        self._resending = threading.Event()
        self._ever_connected = False
        self._acked: list[int] = []
        self._acked_lock = threading.Lock()
        self._inflight = min(s.inflight_max, s.queue_max_messages)

        client = mqtt.Client(mqtt.CallbackAPIVersion.VERSION2, client_id=self.client_id,
                             clean_session=True, protocol=mqtt.MQTTv311)
        if self.broker.username is not None:
            client.username_pw_set(self.broker.username, self.broker.password)
        if self.broker.tls:
            try:
                client.tls_set(ca_certs=s.tls_ca_file)
            except (OSError, ValueError) as exc:  # ssl.SSLError is an OSError
                self.queue.close()
                raise ImuhalError(f"mqtt tls_ca_file {s.tls_ca_file}: cannot load the CA "
                                  f"certificates ({exc}); give a PEM file") from None
        client.max_inflight_messages_set(self._inflight)
        client.max_queued_messages_set(self._inflight)
        client.reconnect_delay_set(min_delay=1, max_delay=s.reconnect_max_s)
        client.on_connect = self._on_connect
        client.on_disconnect = self._on_disconnect
        client.on_connect_fail = self._on_connect_fail
        client.on_publish = self._on_publish
        self._client = client
        self._handed_codes = (mqtt.MQTT_ERR_SUCCESS, mqtt.MQTT_ERR_NO_CONN)
        client.connect_async(self.broker.host, self.broker.port, keepalive=s.keepalive_s)
        client.loop_start()
        self._thread = threading.Thread(target=self._publisher, name="imuhal-mqtt",
                                        daemon=True)
        self._thread.start()

    def describe(self) -> str:
        """Where the messages go (no credentials)."""
        return (f"{self.broker.display()} as client {self.client_id}, topics "
                f"{self._topic_root}#, queue {self.queue.path}")

    # -- pipeline thread -------------------------------------------------------------------

    def handle(self, event: Event) -> None:
        stream = stream_of(event)
        if not self._selector.take(stream):
            return
        seq = self._seq.get(stream, 0)
        self._seq[stream] = seq + 1
        now = time.time()
        payload = encode(event_row(event, self.frame), run=self.run_id, seq=seq, unix_s=now)
        handoff = self._handoff
        if len(handoff) >= self.settings.handoff_max:  # type: ignore[attr-defined]  # the sink's Settings model (MqttSettings) has handoff_max; the base types settings as the base
            with contextlib.suppress(IndexError):  # the publisher may have emptied it
                handoff.popleft()
                self.counts["dropped_handoff"] += 1
        was_empty = not handoff
        handoff.append((self._topic_root + stream, payload, now))
        self.counts["published"] += 1
        if was_empty:
            self._wake.set()

    def close(self) -> None:
        """Stop taking events, send what the queue holds for up to ``close_timeout_s``,
        then disconnect; what is left stays in the queue file for the next run."""
        if self._stop.is_set():
            return
        self._stop.set()
        self._wake.set()
        self._thread.join()
        self._client.disconnect()
        self._client.loop_stop()
        # only when the publisher failed: what it never took from the hand-off is lost
        self.counts["dropped_handoff"] += len(self._handoff)
        self._handoff.clear()
        self.counts["left"] = len(self.queue)
        self.queue.close()

    def run_counts(self) -> dict[str, int]:
        """The counters of the run summary (``COUNTERS``)."""
        return dict(self.counts)

    # -- paho's network thread -------------------------------------------------------------

    def _on_connect(self, client: Any, userdata: Any, flags: Any, reason: Any,
                    properties: Any) -> None:
        if reason.is_failure:
            self._note(f"the broker refused the connection: {reason}")
            return
        if self._ever_connected:
            self.counts["reconnects"] += 1
        if self.last_error is not None:
            self.last_error = None
            print("mqtt: connected; sending the queue", file=sys.stderr)
        self._ever_connected = True
        # paho calls this before it re-sends the unacknowledged messages: new ones wait
        # until those are acknowledged, or they could overtake them (and a receiver keeping
        # the highest seq would then drop a re-sent message that is no duplicate)
        self._resending.set()
        self._connected.set()
        self._wake.set()

    def _on_disconnect(self, client: Any, userdata: Any, flags: Any, reason: Any,
                       properties: Any) -> None:
        self._connected.clear()

    def _on_connect_fail(self, client: Any, userdata: Any) -> None:
        self._note(f"cannot reach {self.broker.display()}; the messages wait in the queue")

    def _on_publish(self, client: Any, userdata: Any, mid: int, reason: Any,
                    properties: Any) -> None:
        with self._acked_lock:
            self._acked.append(mid)
        self._wake.set()

    def _note(self, message: str) -> None:
        if message != self.last_error:
            self.last_error = message
            print(f"mqtt: {message} (retrying)", file=sys.stderr)

    # -- publisher thread ------------------------------------------------------------------

    def _publisher(self) -> None:
        try:
            self._publish_loop()
        except Exception as exc:  # the run goes on; what was not sent is counted, not hidden
            self.failure = f"{type(exc).__name__}: {exc}"
            print(f"mqtt: the publisher stopped ({self.failure}); the rest of the run is "
                  "not published", file=sys.stderr)

    def _publish_loop(self) -> None:
        s: MqttSettings = self.settings  # type: ignore[assignment]  # the plugin's own Settings model: the base class types settings as the base model
        queue = self.queue
        handed = 0  # highest queue id handed to paho
        pending: dict[int, int] = {}  # paho message id -> queue id, until acknowledged
        tokens, last = 0.0, time.monotonic()
        burst = max(1.0, s.drain_rate_msg_s * 0.05)
        deadline: float | None = None
        while True:
            # Idle (nothing queued or awaiting an acknowledgement), only a new event, an
            # acknowledgement or a connection wakes the thread; else it comes back often
            # enough to pace the drain and to see the queue's age limit.
            self._wake.wait(0.05 if len(queue) or pending else 1.0)
            self._wake.clear()
            self._take_handoff(handed)
            self._count_acknowledged(pending)
            now = time.monotonic()
            tokens, last = min(burst, tokens + (now - last) * s.drain_rate_msg_s), now
            room = min(self._inflight - len(pending), int(tokens), len(queue) - len(pending))
            if self._resending.is_set():
                if pending:
                    room = 0  # the re-sent messages go first
                else:
                    self._resending.clear()
            if self._connected.is_set() and room > 0:
                sent, handed = self._hand_over(pending, handed, room)
                tokens -= sent
                if len(queue) > len(pending):
                    self._wake.set()  # more to send: come back as soon as tokens allow
                    time.sleep(min(0.05, 1.0 / s.drain_rate_msg_s))
            if self._stop.is_set():
                if deadline is None:
                    deadline = time.monotonic() + s.close_timeout_s
                if not self._handoff and (len(queue) == 0 or time.monotonic() >= deadline):
                    return

    def _take_handoff(self, handed: int) -> None:
        """Moves the events the pipeline handed over into the queue and applies its limits
        (never dropping what paho holds: ids up to ``handed``)."""
        queue = self.queue
        batch = []
        while self._handoff:
            batch.append(self._handoff.popleft())
        if batch:
            queue.append(batch)
            if not self._connected.is_set():
                self.counts["queued"] += len(batch)
        queue.enforce_limits(time.time(), keep_through_id=handed)
        self.counts["dropped"] = queue.dropped
        self.counts["queue_peak"] = max(self.counts["queue_peak"], len(queue))

    def _count_acknowledged(self, pending: dict[int, int]) -> None:
        """Removes the messages the broker acknowledged from the queue, counting them sent."""
        with self._acked_lock:
            mids, self._acked = self._acked, []
        done = [pending.pop(m) for m in mids if m in pending]
        self.counts["sent"] += self.queue.remove(done)

    def _hand_over(self, pending: dict[int, int], handed: int, room: int) -> tuple[int, int]:
        """Hands up to ``room`` queued messages after ``handed`` to paho: how many it took
        and the highest queue id handed."""
        sent = 0
        for qid, topic, payload in self.queue.after(handed, room):
            info = self._client.publish(topic, payload, qos=1)
            # NO_CONN: paho keeps the message and sends it after reconnecting
            if info.rc not in self._handed_codes:
                break
            pending[info.mid] = qid
            handed = qid
            sent += 1
        return sent, handed


def _paho() -> Any:
    try:
        import paho.mqtt.client as mqtt
    except ImportError:
        raise ImuhalError("the mqtt sink needs paho-mqtt: pip install 'imuhal[mqtt]'") from None
    return mqtt
