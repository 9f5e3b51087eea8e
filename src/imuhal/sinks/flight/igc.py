"""IGC flight log (the FAI's format: A, H, I, L, B and G records), as a sink.

B records (fixes) at whole UTC seconds of the GNSS receiver, every ``interval_s``: position
from the latest fix, validity ``A`` for a 3D fix and ``V`` otherwise (a 2D fix, or the fix
lost: then the last known position with GNSS altitude 0, as SkyDrop writes it), pressure
altitude on the ISA above the 1013.25 hPa datum from the barometer's own pressure (not a
filtered estimate) interpolated to the fix epoch, and GNSS altitude above mean sea level
(header ``HFALGALTGPS:GEO``). The I record declares ``FXA`` (fix accuracy, m) when the
receiver reports one and ``SIU`` (satellites in use) always.

The G record is imuhal's own: ``G`` and the SHA-256 (64 upper-case hex digits) of every byte
of the file before it. It detects corruption and truncation, never tampering (anyone can
recompute it; the file says so in its ``HFFRSSECSUSPECTUSEVALIPROG`` header, and a software
logger cannot hold a secret key). As in SkyDrop's logger (fhorinek/SkyDrop,
``skydrop/src/fc/logger/igc.cpp``) the G record is rewritten after every B record, so a file
cut by a crash still verifies up to its last record: each new B record and the new G record
go to disk in one ``pwrite`` at the offset of the old G record, so a killed process leaves
either the file before the record or the file after it, never half of one. The file is
fsync'ed every ``sync_every_s`` (2 s) of wall time, as the CSV log is: a power cut loses at
most that.

The file is written to ``FILE.partial`` and renamed to ``FILE`` when the run ends (a crashed
run's log stays in ``FILE.partial``, which verifies); a directory as the output gets the FAI
long file name ``YYYY-MM-DD-XXX-LLL-NN.IGC`` (manufacturer ``XXX``: not an approved
manufacturer; ``LLL`` the logger id; ``NN`` the flight of the day, the first number free).

Records are formatted with ``aerofiles`` (``imuhal[igc]``); :func:`verify_igc` needs nothing.
"""

from __future__ import annotations

import hashlib
import io
import math
import os
import re
import time
from bisect import bisect_left
from collections import deque
from collections.abc import Mapping
from dataclasses import dataclass
from datetime import datetime, timezone
from pathlib import Path
from typing import Any, ClassVar

from pydantic import BaseModel, ConfigDict, Field

from imuhal.core.atmosphere import altitude_m_from_pressure
from imuhal.core.atomic import AtomicFile, check_writable, open_seekable_partial
from imuhal.core.errors import ImuhalError, OutputError
from imuhal.core.samples import FixType, PositionSample, PressureSample
from imuhal.sinks.base import Event, SinkPlugin

MANUFACTURER = "XXX"
"""The IGC code for a manufacturer without an approved logger."""
NOT_APPROVED = "HFFRSSECSUSPECTUSEVALIPROG:not an approved logger, unkeyed G record"
G_RECORD = re.compile(rb"G([0-9A-F]{64})\r\n\Z")
MAX_PRESSURE_GAP_NS = 1_000_000_000
"""A fix further than this from any pressure sample gets pressure altitude 0 (unknown)."""


class IgcLogSettings(BaseModel):
    """The profile's ``outputs.igc`` section: who flies what, and how often a fix is logged."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    pilot: str | None = None
    copilot: str | None = None
    glider_type: str | None = None
    glider_id: str | None = None
    competition_id: str | None = None
    interval_s: int = Field(1, ge=1, le=60)
    """Seconds between B records (IGC times have whole seconds)."""
    logger_id: str = Field("IMU", pattern=r"^[A-Z0-9]{3}$")
    """Three letters or digits: the A record's logger id and the file name's."""


class IgcOutputSettings(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)

    path: str
    """The IGC file, or a folder to put it in under the FAI long file name."""
    log: IgcLogSettings = Field(default_factory=IgcLogSettings)
    logger_type: str = "imuhal"
    """``HFFTYFRTYPE``: manufacturer and model of the logger (the profile's name goes here)."""
    firmware: str = ""
    """``HFRFWFIRMWAREVERSION`` (imuhal's version)."""
    device_drivers: dict[str, str] = Field(default_factory=dict)
    """Device name -> driver name (the profile's): ``HFGPSRECEIVER`` and
    ``HFPRSPRESSALTSENSOR`` name the driver and device that gave the positions and
    pressures."""
    gnss_device: str | None = None
    """The receiver's device name (default: the first that reports a position)."""
    pressure_device: str | None = None
    """The barometer's device name (default: the first that reports a pressure)."""
    sync_every_s: float = Field(2.0, gt=0)
    """Wall-time seconds between fsyncs: what a power cut may lose."""


def fai_file_name(date: datetime, logger_id: str, flight: int) -> str:
    """The FAI long file name ``YYYY-MM-DD-XXX-LLL-NN.IGC``."""
    return f"{date:%Y-%m-%d}-{MANUFACTURER}-{logger_id}-{flight:02d}.IGC"


def _free_fai_path(folder: Path, date: datetime, logger_id: str) -> Path:
    """The first flight number of the day whose file (or its ``.partial``) does not exist."""
    for flight in range(1, 100):
        path = folder / fai_file_name(date, logger_id, flight)
        if not path.exists() and not path.with_name(path.name + ".partial").exists():
            return path
    raise ImuhalError(f"--igc {folder}: 99 flights on {date:%Y-%m-%d} already; move them "
                      "elsewhere or name a file")


def check_igc_output(path: str) -> None:
    """Before the run: a folder must exist and be writable; a file path must be writable."""
    p = Path(path)
    if path.endswith(("/", os.sep)) and not p.is_dir():
        raise ImuhalError(f"--igc {path}: folder does not exist; create it first "
                          f"(mkdir -p {path}) or name a file")
    try:
        if p.is_dir():
            probe = p / ".imuhal-igc-probe"
            check_writable(probe, "--igc")
        else:
            check_writable(p, "--igc")
    except OutputError as exc:
        raise ImuhalError(str(exc)) from None


class IgcSink(SinkPlugin):
    """Writes the IGC log of a run (module docstring). ``path`` is known once the first fix
    has given the date; ``b_records`` counts the fixes logged."""

    name: ClassVar[str] = "igc"
    description: ClassVar[str] = "IGC flight log: B records from the GNSS and the barometer"
    Settings = IgcOutputSettings

    def __init__(self, settings: IgcOutputSettings | Mapping[str, Any] | None = None
                 ) -> None:
        super().__init__(settings)
        self.settings: IgcOutputSettings
        try:
            from aerofiles.igc import Writer
        except ImportError:
            raise ImuhalError("--igc needs the aerofiles package: pip install "
                              "'imuhal[igc]'") from None
        self._writer_cls = Writer
        self._writer: Any = None
        self._fix_extensions: list[tuple[str, int]] = []
        check_igc_output(self.settings.path)
        self.path: Path | None = None
        self.b_records = 0
        self._file: AtomicFile | None = None
        self._fd = -1
        self._sha = hashlib.sha256()
        self._g_offset = 0
        self._pressures: deque[tuple[int, float]] = deque()
        self._last_fix: PositionSample | None = None
        self._last_second: int | None = None
        self._last_sync = time.monotonic()

    # -- events -----------------------------------------------------------------------------

    def handle(self, event: Event) -> None:
        s = self.settings
        if isinstance(event, PressureSample):
            if not event.valid:
                return
            if s.pressure_device is None:
                self.settings = s.model_copy(update={"pressure_device": event.device})
            elif event.device != s.pressure_device:
                return
            self._pressures.append((event.t_ns, event.pressure_pa))
            while self._pressures and event.t_ns - self._pressures[0][0] > 3e9:
                self._pressures.popleft()
        elif isinstance(event, PositionSample):
            if s.gnss_device is None:
                self.settings = s.model_copy(update={"gnss_device": event.device})
            elif event.device != s.gnss_device:
                return
            self._position(event)

    def _position(self, pos: PositionSample) -> None:
        has_fix = pos.valid and pos.fix_type in (FixType.FIX_2D, FixType.FIX_3D)
        if has_fix:
            self._last_fix = pos
        if pos.utc_s is None or not math.isfinite(pos.utc_s) or self._last_fix is None:
            return  # no time, or no position ever: nothing to log yet
        second = math.floor(round(pos.utc_s, 3))
        if self._last_second is not None and second < self._last_second + \
                self.settings.log.interval_s:
            return
        if self._writer is None:
            if not has_fix:
                return
            self._open(datetime.fromtimestamp(second, tz=timezone.utc), pos)
        self._last_second = second
        self._write_fix(pos, second, has_fix)

    # -- writing ----------------------------------------------------------------------------

    def _open(self, date: datetime, first: PositionSample) -> None:
        s = self.settings
        target = Path(s.path)
        if target.is_dir():
            target = _free_fai_path(target, date, s.log.logger_id)
        buf = io.BytesIO()
        self._writer = self._writer_cls(buf)
        w = self._writer
        log = s.log
        # Header by header (aerofiles' write_headers would claim a 500 m fix accuracy for a
        # receiver that reports none).
        w.write_logger_id(MANUFACTURER, log.logger_id)
        w.write_date(date.date())
        if first.horizontal_accuracy_m is not None:
            w.write_fix_accuracy(_accuracy_m(first.horizontal_accuracy_m))
        w.write_pilot(log.pilot or "")
        if log.copilot:
            w.write_copilot(log.copilot)
        w.write_glider_type(log.glider_type or "")
        w.write_glider_id(log.glider_id or "")
        w.write_gps_datum()
        w.write_firmware_version(s.firmware)
        w.write_logger_type(s.logger_type)
        w.write_gps_receiver(self._describe(s.gnss_device))
        w.write_pressure_sensor(self._describe(s.pressure_device))
        if log.competition_id:
            w.write_competition_id(log.competition_id)
        w.write_line("HFALGALTGPS:GEO")
        w.write_line("HFALPALTPRESSURE:ISA")
        w.write_line(NOT_APPROVED)
        ext: list[tuple[str, int]] = []
        if first.horizontal_accuracy_m is not None:
            ext.append(("FXA", 3))
        ext.append(("SIU", 2))
        self._fix_extensions = ext
        w.write_fix_extensions(ext)
        w.write_comment(MANUFACTURER, "G: SHA-256 of all bytes before it (imuhal igc verify)")
        # The header is made before the file exists, so that it follows the file's creation
        # at once: a run killed in between leaves an empty FILE.partial (verify_igc: "is
        # empty"), and the wider that window, the likelier (a killed test run hit it on a
        # loaded machine while aerofiles formatted the headers)
        self._file = open_seekable_partial(target, "--igc",
                                           "the IGC log rewrites its G record in place")
        self.path = target
        assert self._file.file is not None
        self._fd = self._file.file.fileno()
        self._append(buf.getvalue())

    def _describe(self, device: str | None) -> str:
        if device is None:
            return "none"
        driver = self.settings.device_drivers.get(device)
        return f"{driver} driver,device {device}" if driver else f"device {device}"

    def _write_fix(self, pos: PositionSample, second: int, has_fix: bool) -> None:
        assert self._writer is not None and self._last_fix is not None
        fix = self._last_fix
        valid = has_fix and pos.fix_type == FixType.FIX_3D
        extensions: list[Any] = []
        for code, _ in self._fix_extensions:
            if code == "FXA":
                acc = pos.horizontal_accuracy_m if has_fix else None
                extensions.append(999 if acc is None else _accuracy_m(acc))
            else:
                extensions.append(min(pos.satellites if has_fix else 0, 99))
        pressure_alt = self._pressure_altitude(pos.t_ns)
        buf = io.BytesIO()
        self._writer.fp = buf
        self._writer.write_fix(
            datetime.fromtimestamp(second, tz=timezone.utc).time(),
            # Rounded to the record's 0.001 minute first: aerofiles rounds the minutes
            # alone, which turns 59.9996' into "60000".
            latitude=round(fix.latitude_deg * 60000) / 60000,
            longitude=round(fix.longitude_deg * 60000) / 60000,
            valid=valid,
            pressure_alt=0 if pressure_alt is None else _clamp_altitude(pressure_alt),
            gps_alt=_clamp_altitude(pos.height_m) if valid else 0,
            extensions=extensions or None)
        self._append(buf.getvalue())
        self.b_records += 1

    def _pressure_altitude(self, t_ns: int) -> float | None:
        """ISA pressure altitude (m, 1013.25 hPa datum) of the barometer at ``t_ns``,
        interpolated between the samples around it (None: none within a second)."""
        ps = self._pressures
        if not ps:
            return None
        times = [t for t, _ in ps]
        i = bisect_left(times, t_ns)
        if 0 < i < len(ps):
            (t0, p0), (t1, p1) = ps[i - 1], ps[i]
            p = p0 + (p1 - p0) * (t_ns - t0) / (t1 - t0) if t1 != t0 else p1
        else:
            t_near, p = ps[0] if i == 0 else ps[-1]
            if abs(t_near - t_ns) > MAX_PRESSURE_GAP_NS:
                return None
        return altitude_m_from_pressure(p)

    def _append(self, records: bytes) -> None:
        """Write ``records`` and the new G record where the old G record starts, in one
        system call (a killed process leaves the file before or after, never between)."""
        self._sha.update(records)
        g = b"G" + self._sha.hexdigest().upper().encode("ascii") + b"\r\n"
        try:
            os.pwrite(self._fd, records + g, self._g_offset)
        except OSError as exc:
            raise ImuhalError(f"--igc {self.path}: cannot be written: {exc.strerror or exc}; "
                              "free some space or choose another path") from None
        self._g_offset += len(records)
        now = time.monotonic()
        if now - self._last_sync >= self.settings.sync_every_s:
            os.fsync(self._fd)
            self._last_sync = now

    def close(self) -> None:
        if self._file is not None:
            self._file.commit()
            self._file = None

    def abort(self) -> Path | None:
        """The run failed: the log stays in ``FILE.partial`` (it verifies), ``FILE`` is
        untouched."""
        if self._file is None:
            return None
        kept = self._file.abort(keep_partial=True)
        self._file = None
        return kept


def _accuracy_m(acc_m: float) -> int:
    """Whole metres, rounded up (never better than the receiver said), at most 999."""
    return min(math.ceil(acc_m), 999)


def _clamp_altitude(m: float) -> int:
    """Whole metres in the B record's five characters (-9999 .. 99999)."""
    return max(-9999, min(99999, round(m)))


# -- verification --------------------------------------------------------------------------

class IgcCheckError(ImuhalError):
    """The file does not verify; the message says why, in one line."""


@dataclass(frozen=True)
class IgcCheck:
    """What a verified file holds."""

    records: int
    b_records: int
    first_fix: str | None
    last_fix: str | None


def verify_igc(path: str | os.PathLike[str]) -> IgcCheck:
    """Check an imuhal IGC file's G record: the last line is ``G`` and the SHA-256 of every
    byte before it. Raises :class:`IgcCheckError` naming the first problem."""
    p = Path(path)
    try:
        data = p.read_bytes()
    except OSError as exc:
        raise IgcCheckError(f"{p}: cannot be read: {exc.strerror or exc}") from None
    return check_igc_bytes(data, str(p))


def check_igc_bytes(data: bytes, p: str = "IGC file") -> IgcCheck:
    """:func:`verify_igc` of a file's contents; ``p`` names it in the messages."""
    if not data:
        raise IgcCheckError(f"{p}: is empty: its run was stopped before it logged anything")
    if not data.startswith(b"A"):
        raise IgcCheckError(f"{p}: not an IGC file (it must start with an A record)")
    end = data.rfind(b"\r\nG")
    match = G_RECORD.match(data, end + 2) if end >= 0 else None
    if match is None:
        raise IgcCheckError(f"{p}: does not end with imuhal's G record (G and 64 hex "
                            "digits): the file was cut or changed, or not written by imuhal")
    body = data[:end + 2]
    if hashlib.sha256(body).hexdigest().upper().encode("ascii") != match.group(1):
        raise IgcCheckError(f"{p}: the G record does not match the records before it: the "
                            "file was changed or corrupted")
    lines = body[:-2].split(b"\r\n")
    for i, line in enumerate(lines, 1):
        if not line or b"\r" in line or b"\n" in line or not line.isascii():
            raise IgcCheckError(f"{p}: line {i} is not an IGC record")
    fixes = [ln for ln in lines if ln.startswith(b"B")]
    def hms(b: bytes) -> str:
        return f"{b[1:3].decode()}:{b[3:5].decode()}:{b[5:7].decode()}"
    return IgcCheck(records=len(lines), b_records=len(fixes),
                    first_fix=hms(fixes[0]) if fixes else None,
                    last_fix=hms(fixes[-1]) if fixes else None)
