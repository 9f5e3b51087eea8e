"""The built-in sinks: a live console line, a CSV log, or your own callback.

CSV format (docs/output-csv.md): one row per event; ``kind`` says which columns it fills.
Columns carry their unit and frame: body-frame NED samples, body -> NED quaternions by
default; with ``frame`` (the profile's ``output_frame``) body-frame vectors, quaternions and
Euler angles are in that convention and their column names carry its suffix.
"""

from __future__ import annotations

import csv
import math
import os
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import IO

from imuhal.core.atomic import AtomicFile
from imuhal.core.conventions import NED, Convention, get_convention
from imuhal.core.samples import (
    Frame,
    PositionSample,
    PressureSample,
    Quantity,
    Sample,
    TemperatureSample,
    VectorSample,
    VelocitySample,
)
from imuhal.estimation.framed import (
    EULER_COLUMNS,
    QUAT_COLUMNS,
    VECTOR_COLUMNS,
    attitude_columns,
    express_attitude,
    express_sample,
    linear_accel_columns,
    vector_columns,
)
from imuhal.estimation.outputs import (
    AttitudeEstimate,
    Estimate,
    RejectedEstimate,
    VerticalEstimate,
)
from imuhal.sinks.base import Event


def csv_columns(frame: str | Convention = NED) -> tuple[str, ...]:
    """The CSV header for events expressed in ``frame`` (docs/output-csv.md): frame-dependent
    columns carry its name as a suffix (none for ned), linear acceleration its earth axes."""
    return (
        "t_s", "source", "kind", "flags",
        *vector_columns(Quantity.ACCEL, frame),
        *vector_columns(Quantity.GYRO, frame),
        *vector_columns(Quantity.MAG, frame),
        "pressure_pa", "temperature_degc",
        *attitude_columns(frame),
        *linear_accel_columns(frame),
        "altitude_m", "climb_m_s", "accel_bias_m_s2",
        *GNSS_COLUMNS,
    )


GNSS_COLUMNS = (
    "latitude_deg", "longitude_deg", "height_msl_m", "fix_type", "satellites",
    "horizontal_accuracy_m", "vertical_accuracy_m", "vn_m_s", "ve_m_s", "vd_m_s",
    "speed_accuracy_m_s",
)
"""GNSS position and earth-frame velocity (frame-independent: NED velocity in every
convention, WGS-84 degrees)."""


CSV_COLUMNS = csv_columns(NED)
"""The header in imuhal's own convention (body-frame NED samples, body -> NED quaternions)."""
NED_LINEAR_ACCEL = linear_accel_columns(NED)


class CallbackSink:
    """Calls ``fn(event)`` for every event (or only for estimates with ``estimates_only``)."""

    def __init__(self, fn: Callable[[Event], None], *, estimates_only: bool = False) -> None:
        self.fn = fn
        self.estimates_only = estimates_only

    def handle(self, event: Event) -> None:
        if self.estimates_only and not isinstance(event, Estimate):
            return
        self.fn(event)

    def close(self) -> None:
        return None


def event_row(event: Event, frame: str | Convention = NED) -> dict[str, str]:
    """The CSV row of one event: only the columns its kind fills; body-frame vectors and
    attitudes expressed in ``frame``."""
    conv = get_convention(frame)
    row: dict[str, str] = {}
    if isinstance(event, Sample):
        row["t_s"] = f"{event.t_ns / 1e9:.6f}"
        row["source"] = event.device
        row["kind"] = event.channel.value
        row["flags"] = str(int(event.flags))
        if isinstance(event, VectorSample):
            if conv is NED:
                _put(row, VECTOR_COLUMNS[event.channel], event.vector)
            elif event.frame is Frame.BODY_NED:
                cols = express_sample(event, conv).columns()
                _put(row, tuple(cols), tuple(cols.values()))
            # a chip-frame vector has no body axes to re-express: other frames leave it out
        elif isinstance(event, PressureSample):
            _put(row, ("pressure_pa",), (event.pressure_pa,))
        elif isinstance(event, TemperatureSample):
            _put(row, ("temperature_degc",), (event.temperature_degc,))
        elif isinstance(event, PositionSample):
            _put(row, ("latitude_deg", "longitude_deg", "height_msl_m"),
                 (event.latitude_deg, event.longitude_deg, event.height_m))
            row["fix_type"] = str(int(event.fix_type))
            row["satellites"] = str(event.satellites)
            for name, value in (("horizontal_accuracy_m", event.horizontal_accuracy_m),
                                ("vertical_accuracy_m", event.vertical_accuracy_m)):
                if value is not None:
                    _put(row, (name,), (value,))
        elif isinstance(event, VelocitySample):
            _put(row, ("vn_m_s", "ve_m_s", "vd_m_s"), event.velocity_ned_m_s)
            if event.accuracy_m_s is not None:
                _put(row, ("speed_accuracy_m_s",), (event.accuracy_m_s,))
        return row
    row["t_s"] = f"{event.t_ns / 1e9:.6f}"
    row["source"] = event.source
    row["flags"] = "0"
    if isinstance(event, RejectedEstimate):
        # the pipeline refused it: its kind and why, never a value
        row["kind"] = event.kind
        row["flags"] = str(int(event.flags))
    elif isinstance(event, AttitudeEstimate):
        row["kind"] = "attitude"
        if conv is NED:
            _put(row, QUAT_COLUMNS, event.q_body_to_ned)
            _put(row, EULER_COLUMNS, event.roll_pitch_yaw_deg)
            if event.linear_accel_ned_m_s2 is not None:
                _put(row, NED_LINEAR_ACCEL, event.linear_accel_ned_m_s2)
        else:
            cols = express_attitude(event, conv).columns()
            _put(row, tuple(cols), tuple(cols.values()))
    elif isinstance(event, VerticalEstimate):
        row["kind"] = "vertical"
        _put(row, ("altitude_m", "climb_m_s"), (event.altitude_m, event.climb_m_s))
        if event.accel_bias_m_s2 is not None:
            _put(row, ("accel_bias_m_s2",), (event.accel_bias_m_s2,))
    else:
        row["kind"] = type(event).__name__
    return row


def _put(row: dict[str, str], names: tuple[str, ...], values: tuple[float, ...]) -> None:
    for name, value in zip(names, values, strict=True):
        row[name] = repr(float(value)) if math.isfinite(value) else "nan"


class CsvSink:
    """Writes events to a CSV log that is never lost and never replaces a good file by a
    failed run's output (docs/output-csv.md, "Safety"):

    * rows go to ``PATH.partial`` beside ``PATH``, flushed and fsync'ed at least every
      ``sync_every_s`` seconds of wall time, so a power cut loses at most that much;
    * :meth:`close` (the run ended, or was stopped by a signal) renames it over ``PATH``;
    * :meth:`abort` (the run failed) leaves ``PATH`` as it was and keeps the rows written so
      far in ``PATH.partial`` (nothing, when there were none); ``partial_path`` says where.

    A FIFO or character device as ``path`` is written directly. ``frame`` names the
    convention of the vector columns (default NED).
    """

    def __init__(self, path: str | os.PathLike[str], *, include_samples: bool = False,
                 frame: str | Convention = NED, sync_every_s: float = 2.0) -> None:
        self.path = Path(path)
        self.include_samples = include_samples
        self.frame = get_convention(frame)
        self.sync_every_s = sync_every_s
        self.rows = 0
        self.partial_path: Path | None = None
        self.committed = False
        """True once :meth:`close` put the whole log under ``path``."""
        self._out: AtomicFile | None = AtomicFile(self.path, newline="", partial=True)
        self._writer = csv.DictWriter(self._out, fieldnames=csv_columns(self.frame),
                                      restval="")
        self._writer.writeheader()
        self._out.sync()  # the log's name is on disk from the start
        self._last_sync = time.monotonic()

    def handle(self, event: Event) -> None:
        if isinstance(event, Sample) and not self.include_samples:
            return
        self._writer.writerow(event_row(event, self.frame))
        self.rows += 1
        if self._out is not None and time.monotonic() - self._last_sync >= self.sync_every_s:
            self._out.sync()
            self._last_sync = time.monotonic()

    def close(self) -> None:
        if self._out is not None:
            self._out.commit()
            self._out = None
            self.committed = True

    def abort(self) -> Path | None:
        """Leave ``path`` as it was; keep the rows written so far in ``path.partial`` (returned)
        when there are any, else write nothing."""
        if self._out is not None:
            self.partial_path = self._out.abort(keep_partial=self.rows > 0)
            self._out = None
        return self.partial_path


class ConsoleSink:
    """A live one-line status: latest altitude, climb rate and attitude, refreshed a few
    times per second of wall time (or every ``every_s`` simulated seconds when not a TTY)."""

    def __init__(self, stream: IO[str] | None = None, *, every_s: float = 1.0,
                 frame: str | Convention = NED) -> None:
        self.frame = get_convention(frame)
        self.stream = stream if stream is not None else sys.stdout
        self.tty = getattr(self.stream, "isatty", lambda: False)()
        self.every_ns = round(every_s * 1e9)
        self._last_print_ns: int | None = None
        self._last_wall = 0.0
        self.vertical: VerticalEstimate | None = None
        self.attitude: AttitudeEstimate | None = None
        self.flagged = 0

    def handle(self, event: Event) -> None:
        if isinstance(event, VerticalEstimate):
            self.vertical = event
        elif isinstance(event, AttitudeEstimate):
            self.attitude = event
        elif isinstance(event, Sample) and not event.valid:
            self.flagged += 1
        t_ns = event.t_ns
        if self.vertical is None and self.attitude is None:
            return  # nothing to show yet (e.g. start-up gyro offsets being measured)
        if self.tty:
            now = time.monotonic()
            if now - self._last_wall < 0.2:
                return
            self._last_wall = now
        elif self._last_print_ns is not None and t_ns - self._last_print_ns < self.every_ns:
            return
        self._last_print_ns = t_ns
        self._emit(self.status_line(t_ns))

    def status_line(self, t_ns: int) -> str:
        parts = [f"t={t_ns / 1e9:8.2f} s"]
        if self.vertical is not None:
            v = self.vertical
            parts.append(f"alt {v.altitude_m:8.2f} m  climb {v.climb_m_s:+6.2f} m/s")
        if self.attitude is not None:
            r, p, y = express_attitude(self.attitude, self.frame).euler_deg
            where = "" if self.frame is NED else f" ({self.frame.name})"
            parts.append(f"roll {r:+6.1f} pitch {p:+6.1f} yaw {y:+7.1f} deg{where}")
        if self.flagged:
            parts.append(f"flagged {self.flagged}")
        return "  ".join(parts)

    def _emit(self, line: str) -> None:
        if self.tty:
            self.stream.write("\r" + line + "\x1b[K")
        else:
            self.stream.write(line + "\n")
        self.stream.flush()

    def close(self) -> None:
        if self.tty:
            self.stream.write("\n")
            self.stream.flush()
