"""The ``foxglove`` sink: the run's events as a live Foxglove WebSocket stream (``foxglove-sdk``,
the ``foxglove`` extra, imported only when a sink is opened; docs/outputs.md, "Foxglove").

Channels, created when a stream's first event arrives:

* ``/<source>/<kind>`` (``/imu/accel``, ``/baro/pressure``, ``/ahrs/attitude``): one JSON
  message per event whose keys are the CSV log's columns (docs/output-csv.md: the unit in
  every name, ``t_s`` the run's clock, ``flags`` 0 = valid; body-frame vectors and attitudes
  in the ``frame`` convention with its suffix, as the MQTT payload has them). NaN is null.
* ``/<source>/tf`` for each attitude estimator: a ``foxglove.FrameTransform`` (a well-known
  schema the 3D panel draws) from the parent frame ``enu`` (x east, y north, z up) to the
  child frame ``<board>/<source>``, the body in FLU (x forward, y left, z up): REP-103, the
  ``enu`` convention whatever ``frame`` says, since the 3D panel is right-handed z-up.

Messages carry the wall-clock log time (when the sink handed them over): Foxglove's live
view orders by it. The server listens on the loopback unless ``host`` names another
address, like the live view (docs/live-view.md).
"""

from __future__ import annotations

import json
from collections.abc import Mapping
from typing import Any, ClassVar

from pydantic import BaseModel, ConfigDict, Field, field_validator

from imuhal.core.conventions import convention_name
from imuhal.core.errors import ImuhalError
from imuhal.estimation.outputs import AttitudeEstimate
from imuhal.sinks.base import Event, SinkPlugin
from imuhal.sinks.builtin import event_row
from imuhal.sinks.mqtt.payload import StreamSelector, stream_of, topic_level
from imuhal.sinks.ros.messages import quat_flu_to_enu

PARENT_FRAME = "enu"
"""The transforms' parent frame: the earth frame, x east, y north, z up (REP-103)."""


class FoxgloveSettings(BaseModel):
    """Settings of the ``foxglove`` sink (profile ``outputs.foxglove``, ``--sink-set
    foxglove.KEY=VALUE``). ``board`` and ``frame`` default to the run's profile name and
    output frame."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    host: str = "127.0.0.1"
    """Address the WebSocket server binds to: the loopback by default (``0.0.0.0`` serves
    every interface; the stream has no authentication)."""
    port: int = Field(8765, ge=0, le=65535)
    """TCP port (8765: Foxglove's default); 0 picks a free one (the run prints it)."""
    board: str = "board"
    """The server's name and the first part of the transforms' child frame."""
    frame: str = "ned"
    """Convention of the JSON messages' frame-dependent columns (docs/units-and-frames.md)."""
    streams: tuple[str, ...] = ("*",)
    """Streams served (fnmatch patterns of ``source/kind``: ``ahrs/*``, ``*/pressure``)."""

    @field_validator("streams", mode="before")
    @classmethod
    def _one_pattern(cls, value: Any) -> Any:
        return (value,) if isinstance(value, str) else value

    _frame = field_validator("frame")(convention_name)


def _foxglove() -> Any:
    """The ``foxglove`` module, or one line saying which extra to install."""
    try:
        import foxglove
        import foxglove.messages
    except ImportError as exc:
        raise ImuhalError(f"--sink foxglove needs the 'foxglove' extra ({exc.name} is "
                          "missing): pip install 'imuhal[foxglove]'") from None
    return foxglove


def json_message(row: Mapping[str, str]) -> dict[str, float | int | None]:
    """An event's CSV row (``event_row``) as a JSON object: every filled column but
    ``source`` and ``kind`` (in the topic), as numbers, NaN as null."""
    return {key: None if value == "nan" else json.loads(value)
            for key, value in row.items() if key not in ("source", "kind")}


def json_schema(message: Mapping[str, Any]) -> dict[str, Any]:
    """The JSON schema Foxglove is told for a stream (its columns, for the panels' field
    pickers): every column a number, null for a missing value."""
    return {"type": "object",
            "properties": {key: {"type": ["number", "null"]} for key in message}}


class FoxgloveSink(SinkPlugin):
    """Serves the run live to Foxglove over its WebSocket protocol (module docstring).
    ``messages`` counts the messages logged (a message with no client connected is
    dropped by the server, not queued)."""

    name: ClassVar[str] = "foxglove"
    description: ClassVar[str] = ("live Foxglove WebSocket stream (foxglove-sdk): JSON per "
                                  "stream, FrameTransform of each attitude; loopback")
    Settings = FoxgloveSettings

    def __init__(self, settings: FoxgloveSettings | Mapping[str, Any] | None = None) -> None:
        super().__init__(settings)
        self.settings: FoxgloveSettings
        s = self.settings
        self._fg = _foxglove()
        self._context = self._fg.Context()
        self._selector = StreamSelector(s.streams, {})
        self._channels: dict[str, Any] = {}
        self.messages = 0
        try:
            self.server = self._fg.start_server(name=f"imuhal {s.board}", host=s.host,
                                                port=s.port, context=self._context)
        except RuntimeError as exc:  # the SDK's error for an address it cannot bind
            raise ImuhalError(f"--sink foxglove: cannot listen on {s.host}:{s.port}: {exc}; "
                              "choose another port (foxglove.port=0 picks a free one)"
                              ) from None
        self.port: int = self.server.port

    def describe(self) -> str:
        """Where to connect."""
        return (f"ws://{self.settings.host}:{self.port} (Foxglove: Open connection > "
                "Foxglove WebSocket)")

    def handle(self, event: Event) -> None:
        stream = stream_of(event)
        if not self._selector.take(stream):
            return
        message = json_message(event_row(event, self.settings.frame))
        channel = self._channels.get(stream)
        if channel is None:
            channel = self._channels[stream] = self._fg.Channel(
                f"/{stream}", schema=json_schema(message), context=self._context)
        channel.log(message)
        self.messages += 1
        if isinstance(event, AttitudeEstimate):
            self._transform(event)

    def _transform(self, est: AttitudeEstimate) -> None:
        source = topic_level(est.source)
        topic = f"/{source}/tf"
        channel = self._channels.get(topic)
        if channel is None:
            channel = self._channels[topic] = self._fg.channels.FrameTransformChannel(
                topic, context=self._context)
        m = self._fg.messages
        w, x, y, z = quat_flu_to_enu(est.q_body_to_ned)
        channel.log(m.FrameTransform(
            timestamp=m.Timestamp.now(), parent_frame_id=PARENT_FRAME,
            child_frame_id=f"{self.settings.board}/{source}",
            translation=m.Vector3(x=0.0, y=0.0, z=0.0),
            rotation=m.Quaternion(x=x, y=y, z=z, w=w)))
        self.messages += 1

    def run_counts(self) -> dict[str, int]:
        """The run summary's count: messages logged."""
        return {"messages": self.messages}

    def close(self) -> None:
        self.server.stop()
