"""The MCAP sink: the run's samples and estimates as ROS 2 messages in an MCAP file.

Messages are the ones :class:`~imuhal.sinks.ros.messages.RosMessages` makes (REP-103 frames,
REP-145 topics), CDR-encoded by ``mcap-ros2-support`` into a chunked, indexed MCAP file
(profile ``ros2``, zstd chunks), the format ``ros2 bag`` writes by default since Iron.

Safety, as for the CSV log (imuhal.core.atomic): the file is written as ``PATH.partial``
beside ``PATH`` and renamed over it when the run ends; a failed run leaves ``PATH`` as it
was. A run killed outright (SIGKILL, a power cut) leaves ``PATH.partial`` readable up to its
last chunk: a chunk is closed at least every ``chunk_s`` seconds of the run's time and of
wall time, and lands in the file together with an MCAP footer without a summary section, in
one positioned write, fsync'ed; the next chunk lands over that footer the same way. A reader
finding that footer scans the chunks (rosbags, ``ros2 bag``, Foxglove), so at most
``chunk_s`` of data is lost. The library's output is held in memory between landings
(:class:`StagedFile`): written through, a chunk overwrote the footer several writes before
its own footer followed, and a kill in between left a file no reader opens.
"""

from __future__ import annotations

import contextlib
import os
import struct
import time
from collections.abc import Iterator, Mapping
from pathlib import Path
from typing import Any, ClassVar, Literal

from pydantic import BaseModel, ConfigDict, Field

from imuhal.core.atomic import AtomicFile, open_seekable_partial
from imuhal.core.errors import ImuhalError
from imuhal.sinks.base import Event, SinkPlugin
from imuhal.sinks.ros.messages import MSGDEFS, RosMessages, RosRecord
from imuhal.sinks.ros.settings import RosSettings

MCAP_MAGIC = b"\x89MCAP0\r\n"
_FOOTER_OPCODE = 0x02
# Footer: opcode, record length (20), summary_start = 0 and summary_offset_start = 0 (no
# summary: readers scan the data section), summary_crc = 0, then the closing magic.
FOOTER_NO_SUMMARY = struct.pack("<BQQQI", _FOOTER_OPCODE, 20, 0, 0, 0) + MCAP_MAGIC


class StagedFile:
    """The MCAP writer's output stream: bytes are held in memory until :meth:`land` writes
    them, and a trailer after them, at the file's end in one ``pwrite`` and fsyncs. A kill
    finds the file as it was before that write or after it (short of a cut inside the
    one system call), never in the middle of a chunk's records."""

    def __init__(self, file: Any) -> None:
        file.flush()
        self._file = file  # kept open as long as this stream is
        self._fd: int = file.fileno()
        self._pos: int = file.tell()
        self._held = bytearray()

    def write(self, data: bytes | bytearray | memoryview) -> int:
        self._held += data
        return len(data)

    def tell(self) -> int:
        """Where the next byte goes, as the writer's indexes must record it."""
        return self._pos + len(self._held)

    def flush(self) -> None:
        """Nothing: the writer's flushes land only with :meth:`land`."""

    def land(self, trailer: bytes = b"") -> None:
        """Write what is held and then ``trailer`` at the end; the trailer is overwritten by
        the next landing (what is held is written over it first)."""
        data = memoryview(bytes(self._held) + trailer)
        at = self._pos
        while data:
            n = os.pwrite(self._fd, data, at)
            data, at = data[n:], at + n
        os.fsync(self._fd)
        self._pos += len(self._held)
        self._held.clear()

    def end(self) -> None:
        """Land what is held and cut the file there (no earlier trailer may remain)."""
        self.land()
        os.ftruncate(self._fd, self._pos)


CHUNK_MEMORY_BYTES = 64 << 20
"""The chunk size at which the library itself would close one (a memory bound only)."""


class McapOutputSettings(BaseModel):
    """Where to write and how often a chunk is closed."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    path: str
    """The MCAP file (written as ``path.partial`` until the run ends)."""
    ros: RosSettings = Field(default_factory=RosSettings)
    """Frame id and noise (``imuhal run`` passes the profile's ``outputs.mcap`` section, with
    the board's name as the frame id unless it names one)."""
    chunk_s: float = Field(1.0, gt=0, le=60)
    """A chunk is closed (and the file made readable) at least this often, in the run's time
    and in wall time: at most this much is lost when the process is killed."""
    compression: Literal["zstd", "lz4", "none"] = "zstd"
    metadata: dict[str, str] = Field(default_factory=dict)
    """Written as the MCAP metadata record ``imuhal`` (board, version, ...)."""


def _ros_writer() -> tuple[Any, Any]:
    """The ``mcap-ros2-support`` writer class and mcap's CompressionType, or one line saying
    which extra to install."""
    try:
        from mcap.writer import CompressionType
        from mcap_ros2.writer import Writer
    except ImportError as exc:
        raise ImuhalError(f"--mcap needs the 'ros' extra ({exc.name} is missing): "
                          "pip install 'imuhal[ros]'") from None
    return Writer, CompressionType


class McapSink(SinkPlugin):
    """Writes ROS 2 messages to an MCAP file (module docstring). ``messages`` counts what was
    written, ``records.skipped`` what was not (flagged or sensor-frame samples)."""

    name: ClassVar[str] = "mcap"
    description: ClassVar[str] = ("ROS 2 sensor_msgs (Imu, MagneticField, FluidPressure, "
                                  "Temperature, NavSatFix) in an MCAP file, ENU/FLU")
    Settings = McapOutputSettings

    def __init__(self, settings: McapOutputSettings | Mapping[str, Any] | None = None
                 ) -> None:
        super().__init__(settings)
        self.settings: McapOutputSettings
        s = self.settings
        writer_cls, compression = _ros_writer()
        self.path = Path(s.path)
        self.records = RosMessages(s.ros, s.ros.frame_id or "base_link")
        self.messages = 0
        self.committed = False
        self.partial_path: Path | None = None
        self._out: AtomicFile | None = open_seekable_partial(
            self.path, "--mcap", "an MCAP file is indexed at the end and needs a regular file")
        assert self._out.file is not None
        self._file = StagedFile(self._out.file)
        # Chunks are closed here, each followed by a footer; the library's size limit (which
        # would close one without) only bounds memory, far above a second of any board's data.
        self._writer = writer_cls(
            self._file, chunk_size=CHUNK_MEMORY_BYTES,
            compression={"zstd": compression.ZSTD, "lz4": compression.LZ4,
                         "none": compression.NONE}[s.compression])
        if s.metadata:
            self._writer.add_metadata("imuhal", dict(s.metadata))
        self._schemas: dict[str, Any] = {}
        self._log_ns: int | None = None  # the run's time so far (latest event time)
        self._chunk_first_ns: int | None = None
        self._last_seal = time.monotonic()
        self._seal()  # a readable (empty) file from the start

    def handle(self, event: Event) -> None:
        if self._log_ns is None or event.t_ns > self._log_ns:
            self._log_ns = event.t_ns
        with self._write_errors():
            for record in self.records.convert(event):
                self._write(record)
            self._maybe_seal()

    @contextlib.contextmanager
    def _write_errors(self) -> Iterator[None]:
        """A full disk or an I/O error is the user's to fix: one line naming the file (the
        library writes to it directly, past AtomicFile's own wrapping)."""
        try:
            yield
        except OSError as exc:
            raise ImuhalError(f"--mcap {self.path}: cannot be written: "
                              f"{exc.strerror or exc}; free some space or choose another "
                              "path") from None

    def _write(self, record: RosRecord) -> None:
        schema = self._schemas.get(record.type)
        if schema is None:
            schema = self._schemas[record.type] = self._writer.register_msgdef(
                record.type, MSGDEFS[record.type])
        # log_time: when the message was written, in the run's time (never before the
        # previous one: a GNSS fix arrives after later IMU samples); header.stamp: the time
        # the message describes.
        log_ns = max(record.t_ns, self._log_ns or 0)
        self._writer.write_message(record.topic, schema, record.message, log_time=log_ns,
                                   publish_time=log_ns, sequence=self.messages)
        self.messages += 1
        if self._chunk_first_ns is None:
            self._chunk_first_ns = log_ns

    def _maybe_seal(self) -> None:
        if self._chunk_first_ns is None:
            return
        s = self.settings
        if ((self._log_ns or 0) - self._chunk_first_ns >= s.chunk_s * 1e9
                or time.monotonic() - self._last_seal >= s.chunk_s):
            self._seal()

    def _seal(self) -> None:
        """Close the chunk and land it with a footer after it (durable, readable), which the
        next chunk overwrites."""
        with self._write_errors():
            # mcap-ros2's Writer keeps its mcap Writer, whose flush() closes the chunk, private
            self._writer._writer.flush()
            self._file.land(FOOTER_NO_SUMMARY)
        self._chunk_first_ns = None
        self._last_seal = time.monotonic()

    def _finish(self) -> None:
        self._write_pending()
        self._writer.finish()  # summary, indexes and the real footer
        self._file.end()

    def _write_pending(self) -> None:
        for record in self.records.finish():
            self._write(record)

    def close(self) -> None:
        if self._out is None:
            return
        with self._write_errors():
            self._finish()
        self._out.commit()
        self._out = None
        self.committed = True

    def abort(self) -> Path | None:
        """Leave ``path`` as it was; keep what was written in ``path.partial`` (returned),
        complete with its summary, when there were messages."""
        if self._out is not None:
            # if this fails too, the footer of the last sealed chunk keeps it readable
            with contextlib.suppress(OSError, ValueError):
                self._write_pending()
            keep = self.messages > 0
            if keep:
                with contextlib.suppress(OSError, ValueError):
                    self._finish()
            self.partial_path = self._out.abort(keep_partial=keep)
            self._out = None
        return self.partial_path
