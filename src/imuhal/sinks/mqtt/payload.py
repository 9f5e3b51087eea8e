"""What the MQTT sink publishes: one topic per stream, one compact JSON object per event.

Topic ``<prefix>/<board>/<source>/<kind>`` (default prefix ``imuhal``): ``source`` is the
device (samples) or estimator (estimates) name of the profile, ``kind`` the CSV log's ``kind``
(``accel``, ``pressure``, ``attitude``, ``vertical`` ...). The payload's keys are the CSV log's
columns (docs/output-csv.md: units in the names, frame-dependent columns in the run's output
frame with its suffix), plus ``run``, ``seq`` and ``unix_s``; ``source`` and ``kind`` are in
the topic. NaN is ``null``. docs/outputs.md ("MQTT") documents the format.
"""

from __future__ import annotations

import fnmatch
import re
from collections.abc import Mapping

from imuhal.core.samples import Sample
from imuhal.estimation.outputs import estimate_kind
from imuhal.sinks.base import Event

_NOT_IN_A_LEVEL = re.compile(r"[+#/\x00\s]")
"""MQTT wildcards, the level separator, NUL and white space: not allowed in one topic level."""


def topic_level(name: str) -> str:
    """``name`` as one topic level: wildcards, ``/``, NUL and white space become ``_``."""
    return _NOT_IN_A_LEVEL.sub("_", name) or "_"


def stream_of(event: Event) -> str:
    """The stream an event belongs to: ``source/kind`` (``imu/accel``, ``ahrs/attitude``),
    with the CSV log's ``source`` and ``kind`` (read without building the whole row: most
    events of a decimated stream are never encoded)."""
    if isinstance(event, Sample):
        source, kind = event.device, event.channel.value
    else:
        source = event.source
        kind = estimate_kind(event)
    return f"{topic_level(source)}/{topic_level(kind)}"


def encode(row: Mapping[str, str], *, run: int, seq: int, unix_s: float) -> bytes:
    """The JSON object of one event's CSV row (``event_row``): ``run``, ``seq``, ``unix_s``
    then every filled column but ``source`` and ``kind``, as numbers (NaN as null).

    ``event_row`` renders every value it fills as a JSON number (``repr`` of a float, an
    integer) or ``nan``, so the text is built directly instead of parsing the numbers back.
    """
    parts = [f'"run":{run}', f'"seq":{seq}', f'"unix_s":{unix_s:.6f}']
    for key, value in row.items():
        if key in ("source", "kind"):
            continue
        parts.append(f'"{key}":{"null" if value == "nan" else value}')
    return ("{" + ",".join(parts) + "}").encode("ascii")


class StreamSelector:
    """Which events of which stream are published: ``streams`` (fnmatch patterns of
    ``source/kind``) choose the streams, ``decimate`` (pattern -> N, first match wins)
    publishes every Nth event of a stream (the first one included)."""

    def __init__(self, streams: tuple[str, ...], decimate: Mapping[str, int]) -> None:
        self.streams = streams
        self.decimate = dict(decimate)
        self._every: dict[str, int] = {}
        self._seen: dict[str, int] = {}

    def every(self, stream: str) -> int:
        """1 in how many events of ``stream`` is published (0: none)."""
        n = self._every.get(stream)
        if n is None:
            if not any(fnmatch.fnmatchcase(stream, p) for p in self.streams):
                n = 0
            else:
                n = next((k for p, k in self.decimate.items()
                          if fnmatch.fnmatchcase(stream, p)), 1)
            self._every[stream] = n
        return n

    def take(self, stream: str) -> bool:
        """Whether this event of ``stream`` is published (counts it)."""
        n = self.every(stream)
        if n == 0:
            return False
        seen = self._seen.get(stream, 0)
        self._seen[stream] = seen + 1
        return seen % n == 0
