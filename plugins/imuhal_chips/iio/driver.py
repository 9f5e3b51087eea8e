"""The ``iio`` driver: any chip a Linux kernel IIO driver exports, as imuhal samples.

The kernel driver owns the chip; this driver finds the IIO device by its ``name`` attribute,
reads its accelerometer, gyro (``anglvel``), magnetometer, pressure and temperature channels
and converts them to SI units in the chip's frame. The kernel's units (sysfs-bus-iio: value =
(raw + offset) * scale, or ``_input`` already scaled) differ from the pipeline's:

    accel m/s^2 (specific force, as the chip measures it)  -> m/s^2
    anglvel rad/s                                          -> rad/s
    magn gauss                                             -> uT     (x 100)
    pressure kPa                                           -> Pa     (x 1000)
    temp milli-degC                                        -> degC   (/ 1000)

With ``buffered`` (default) and a device that has scan elements, samples come from the
character device with the kernel's timestamps; otherwise each poll reads the sysfs values.

Lost scans: the kernel's buffer holds ``buffer/length`` scans and drops new ones while it is
full, without telling anyone. A drain that finds it full is counted
(``health.buffer_overflows``) and, with time stamps, the scans dropped are counted from the
gap to the next scan that arrives, in periods of the mean scan interval over the gap-free
stretches seen (``health.scans_lost``); both show in the run summary. A buffer that never
fills claims no loss, so scheduling jitter is never counted as one.
"""

from __future__ import annotations

import re
import statistics
from collections import defaultdict
from dataclasses import dataclass
from itertools import pairwise
from typing import ClassVar

from pydantic import Field

from imuhal.bus.base import BusKind, Link
from imuhal.bus.linux_iio import ATTR_LEN, FOUND, LIST_LEN
from imuhal.core.clock import Clock
from imuhal.core.errors import BusError, ConfigurationError, DeviceNotFoundError, NackError
from imuhal.core.samples import (
    AccelSample,
    Frame,
    GyroSample,
    MagSample,
    PressureSample,
    Quantity,
    Sample,
    TemperatureSample,
)
from imuhal.core.streams import StreamSpec, TimeSource
from imuhal.drivers.base import DeviceHealth, DeviceIdentity, Driver, DriverSettings, PollResult
from imuhal_chips.iio.scan import ScanElement, layout, parse_scan_type

MAX_DEVICES = 64
"""IIO device numbers probed when looking for a name."""

UNIT_TO_SI = {"accel": 1.0, "anglvel": 1.0, "magn": 100.0, "pressure": 1000.0, "temp": 1e-3}
"""Kernel IIO unit -> pipeline unit, per channel type (see the module docstring)."""
VECTOR_TYPES = ("accel", "anglvel", "magn")
QUANTITY_OF = {"accel": Quantity.ACCEL, "anglvel": Quantity.GYRO, "magn": Quantity.MAG,
               "pressure": Quantity.PRESSURE, "temp": Quantity.TEMPERATURE}
"""IIO channel type -> the quantity its samples carry."""
_CHANNEL = re.compile(r"^in_(accel|anglvel|magn|pressure|temp)(?:_([xyz]))?_(raw|input)$")
_SCAN_EN = re.compile(r"^(in_(?:accel|anglvel|magn|pressure|temp)(?:_[xyz])?|in_timestamp)_en$")


class IIODriverSettings(DriverSettings):
    name: str = Field(min_length=1)
    """The IIO device's ``name`` attribute (the kernel driver's part name, e.g. ``bmp280``,
    ``mpu9250``, ``hmc5883l``, ``ms5611``). The profile's ``address`` picks among devices
    of the same name: 0 the first, 1 the second."""
    buffered: bool = True
    """Read the buffered character device when the device has scan elements."""
    sampling_frequency_hz: float | None = Field(None, gt=0)
    """Written to ``sampling_frequency`` when given (the kernel picks the nearest it can)."""
    poll_hz: float = Field(50.0, gt=0, le=2000)
    """How often the buffer is drained, or (unbuffered, without a sampling frequency) how often
    the sysfs values are read."""
    trigger: str | None = None
    """Written to ``trigger/current_trigger`` before the buffer is enabled, for kernel
    drivers with no trigger of their own (e.g. an hrtimer trigger for the ms5611)."""
    buffer_length: int | None = Field(None, ge=2)
    """Written to ``buffer/length`` before the buffer is enabled: how many scans the kernel
    keeps between drains (its default otherwise; keep it above rate / poll_hz)."""


@dataclass
class IIOHealth(DeviceHealth):
    """The driver's own counts plus what the kernel's buffer lost."""

    buffer_overflows: int = 0
    """Drains that found the kernel's buffer full (new scans were being dropped)."""
    scans_lost: int = 0
    """Scans dropped by a full buffer, counted from the time stamps around the gap."""

    def counts(self) -> dict[str, int]:
        return {**super().counts(), "buffer_overflows": self.buffer_overflows,
                "scans_lost": self.scans_lost}


@dataclass(frozen=True)
class IIOChannel:
    type: str
    axis: str
    """``x``, ``y``, ``z`` or empty for a scalar."""
    processed: bool
    """``_input`` (already in kernel units) rather than ``_raw``."""
    scale: float
    offset: float

    @property
    def attribute(self) -> str:
        axis = f"_{self.axis}" if self.axis else ""
        return f"in_{self.type}{axis}_{'input' if self.processed else 'raw'}"

    @property
    def element(self) -> str:
        return f"in_{self.type}{'_' + self.axis if self.axis else ''}"

    def to_si(self, value: float) -> float:
        if not self.processed:
            value = (value + self.offset) * self.scale
        return value * UNIT_TO_SI[self.type]


class IIODriver(Driver):
    name: ClassVar[str] = "iio"
    description: ClassVar[str] = ("a chip bound to a Linux kernel IIO driver: accel, anglvel, "
                                  "magn, pressure, temp channels (bus kind iio)")
    Settings = IIODriverSettings
    channels = (Quantity.ACCEL, Quantity.GYRO, Quantity.MAG, Quantity.PRESSURE,
                Quantity.TEMPERATURE)
    bus_kinds = frozenset({BusKind.IIO})

    settings: IIODriverSettings

    def __init__(self, link: Link, settings: DriverSettings, *, device: str,
                 clock: Clock) -> None:
        super().__init__(link, settings, device=device, clock=clock)
        self._dev: Link | None = None
        self._channels: dict[str, list[IIOChannel]] = {}
        self._scan: list[ScanElement] = []
        self._scan_size = 0
        self._period_ns = round(1e9 / self.settings.poll_hz)
        self._ts_offset_ns: int | None = None
        self._last_t_ns = -1
        self._rate_hz = 0.0
        self.health: IIOHealth = IIOHealth()
        self._buffer_scans = 0
        self._overflowed = False
        """The previous drain found the buffer full: the next scan may follow a gap."""
        self._last_stamp: int | None = None
        self._interval_ns = 0.0
        self._interval_sum_ns = 0
        self._interval_count = 0

    # -- sysfs access through the bus --------------------------------------------------------

    def _read(self, path: str, dev: Link | None = None) -> str | None:
        reply = (dev or self._device()).transfer(b"r" + path.encode(), ATTR_LEN)
        return reply[1:].rstrip(b"\0").decode() if reply[:1] == FOUND else None

    def _list(self, path: str = "") -> list[str]:
        reply = self._device().transfer(b"l" + path.encode(), LIST_LEN)
        text = reply[1:].rstrip(b"\0").decode()
        return text.split("\n") if reply[:1] == FOUND and text else []

    def _write(self, path: str, value: str) -> None:
        self._device().transfer(b"w" + path.encode() + b"\0" + value.encode(), 0)

    def _number(self, path: str, default: float) -> float:
        text = self._read(path)
        if text is None:
            return default
        try:
            return float(text)
        except ValueError:
            raise ConfigurationError(f"{self.describe()}: {path} reads {text!r}, not a "
                                     "number") from None

    def _device(self) -> Link:
        if self._dev is None:
            raise ConfigurationError(f"{self.describe()}: not probed")
        return self._dev

    # -- probe and configure --------------------------------------------------------------

    def probe(self) -> DeviceIdentity:
        wanted, nth = self.settings.name, self.link.target
        seen: list[str] = []
        for number in range(MAX_DEVICES):
            candidate = self.link.bus.link(number)
            try:
                name = self._read("name", candidate)
            except NackError:
                continue
            seen.append(f"iio:device{number}={name}")
            if name == wanted:
                if nth == 0:
                    self._dev = candidate
                    break
                nth -= 1
        else:
            raise DeviceNotFoundError(
                driver=self.name, bus=self.link.bus.name, address=self.link.target,
                expected=f"IIO device named {wanted!r} (number {self.link.target} of that "
                f"name)", found=", ".join(seen) or "no IIO devices",
                hint="is the kernel driver bound (dmesg, /sys/bus/iio/devices/*/name)?")
        self._channels = self._discover()
        if not self._channels:
            raise DeviceNotFoundError(
                driver=self.name, bus=self.link.bus.name, address=self.link.target,
                expected="accel, anglvel, magn, pressure or temp channels",
                found=f"none on {wanted!r}")
        return DeviceIdentity(self.name, self.link.bus.name, self.link.target,
                              f"name={wanted}", note=f"iio:device{self._device().target}")

    def _discover(self) -> dict[str, list[IIOChannel]]:
        found: dict[str, dict[str, IIOChannel]] = defaultdict(dict)
        for attribute in self._list():
            m = _CHANNEL.match(attribute)
            if m is None:
                continue
            ctype, axis, kind = m.group(1), m.group(2) or "", m.group(3)
            if (ctype in VECTOR_TYPES) != bool(axis):
                continue  # e.g. a vector's magnitude channel: not a sample we make
            known = found[ctype].get(axis)
            if known is not None and not known.processed:
                continue  # prefer _raw (with its scale) when both are there
            stem = f"in_{ctype}_{axis}" if axis else f"in_{ctype}"
            shared = f"in_{ctype}"
            processed = kind == "input"
            scale = offset = 0.0
            if not processed:
                scale = self._number(f"{stem}_scale", self._number(f"{shared}_scale", 1.0))
                offset = self._number(f"{stem}_offset", self._number(f"{shared}_offset", 0.0))
            found[ctype][axis] = IIOChannel(ctype, axis, processed, scale, offset)
        out = {}
        for ctype, by_axis in found.items():
            if ctype in VECTOR_TYPES:
                if set(by_axis) == {"x", "y", "z"}:
                    out[ctype] = [by_axis[a] for a in "xyz"]
            else:
                out[ctype] = [by_axis[""]]
        return out

    def configure(self) -> None:
        s = self.settings
        dev = self._device()
        dev.transfer(b"c", 0)  # a fresh buffer after any reconfiguration
        if s.sampling_frequency_hz is not None:
            self._write("sampling_frequency", f"{s.sampling_frequency_hz:g}")
        self._rate_hz = rate = self._number("sampling_frequency", 0.0)
        self._scan, self._scan_size = [], 0
        if s.buffered and self._list("scan_elements"):
            self._configure_buffer()
            self._period_ns = round(1e9 / s.poll_hz)
        else:
            self._period_ns = round(1e9 / (rate if rate > 0 else s.poll_hz))
        self._ts_offset_ns = None

    def streams(self) -> tuple[StreamSpec, ...]:
        """One stream per channel type found, at the ``sampling_frequency`` the kernel
        reads back after configure() (the host's ``poll_hz`` where the device has none).
        Scale: the kernel's ``_scale`` attribute in SI for ``_raw`` channels (None for
        ``_input`` ones, already scaled); no full scale (IIO publishes none). Time stamps:
        the kernel's, in a buffer with ``in_timestamp``; else the poll's."""
        rate_hz = self._rate_hz if self._rate_hz > 0 else self.settings.poll_hz
        stamped = any(e.name == "in_timestamp" for e in self._scan)
        source = TimeSource.KERNEL_BUFFER if stamped else TimeSource.HOST_POLL
        out = []
        for ctype, chans in self._channels.items():
            first = chans[0]
            scale = None if first.processed else first.scale * UNIT_TO_SI[ctype]
            out.append(StreamSpec(
                self.device, QUANTITY_OF[ctype], Frame.SENSOR if ctype in VECTOR_TYPES else None,
                rate_hz, scale=scale, time_source=source))
        return tuple(out)

    def refresh_streams(self) -> tuple[StreamSpec, ...]:
        self._rate_hz = self._number("sampling_frequency", 0.0)
        return self.streams()

    def _configure_buffer(self) -> None:
        s = self.settings
        self._write("buffer/enable", "0")
        decoded = {c.element for chans in self._channels.values() for c in chans}
        elements = []
        for entry in self._list("scan_elements"):
            if not entry.endswith("_en"):
                continue
            m = _SCAN_EN.match(entry)
            wanted = m is not None and (m.group(1) in decoded or m.group(1) == "in_timestamp")
            self._write(f"scan_elements/{entry}", "1" if wanted else "0")
            if wanted:
                name = entry[:-3]
                index = int(self._number(f"scan_elements/{name}_index", -1))
                text = self._read(f"scan_elements/{name}_type") or ""
                try:
                    elements.append((name, index, parse_scan_type(text)))
                except ValueError as exc:
                    raise ConfigurationError(f"{self.describe()}: {name}_type: {exc}") from None
        self._scan, self._scan_size = layout(elements)
        if self._read("current_timestamp_clock") is not None:
            # The pipeline's clock is monotonic; the kernel's default is realtime.
            self._write("current_timestamp_clock", "monotonic")
        if s.trigger is not None:
            self._write("trigger/current_trigger", s.trigger)
        if s.buffer_length is not None:
            self._write("buffer/length", str(s.buffer_length))
        self._buffer_scans = int(self._number("buffer/length", 0))
        self._overflowed, self._last_stamp = False, None
        self._interval_sum_ns = self._interval_count = 0
        self._write("buffer/enable", "1")

    # -- polling ---------------------------------------------------------------------------

    def start(self, now_ns: int) -> int:
        self._last_t_ns = now_ns - 1
        return now_ns + self._period_ns

    def poll(self, now_ns: int) -> PollResult:
        if self._scan:
            return PollResult(self._poll_buffer(now_ns), now_ns + self._period_ns)
        values = {}
        for ctype, chans in self._channels.items():
            values[ctype] = [c.to_si(self._value(c)) for c in chans]
        return PollResult(self._samples(now_ns, values), now_ns + self._period_ns)

    def _value(self, channel: IIOChannel) -> float:
        text = self._read(channel.attribute)
        if text is None:
            raise BusError(f"{channel.attribute} disappeared", bus=self.link.bus.name,
                           target=self._device().target)
        try:
            return float(text)
        except ValueError:
            raise BusError(f"{channel.attribute} reads {text!r}", bus=self.link.bus.name,
                           target=self._device().target) from None

    def _poll_buffer(self, now_ns: int) -> list[Sample]:
        dev = self._device()
        queued = int.from_bytes(dev.transfer(b"n", 4), "little")
        count = queued // self._scan_size
        if count == 0:
            return []
        data = dev.transfer(b"b", count * self._scan_size)
        scans = []
        for i in range(count):
            raw = data[i * self._scan_size:(i + 1) * self._scan_size]
            scans.append({e.name: e.type.decode(raw[e.offset:e.offset + e.type.storage_bytes])
                          for e in self._scan})
        self._count_losses(scans, full=0 < self._buffer_scans <= count)
        times = self._scan_times(now_ns, scans)
        out: list[Sample] = []
        for t_ns, scan in zip(times, scans, strict=True):
            values = {ctype: [c.to_si(scan[c.element]) for c in chans]
                      for ctype, chans in self._channels.items()
                      if all(c.element in scan for c in chans)}
            out += self._samples(t_ns, values)
        return out

    def _count_losses(self, scans: list[dict[str, float]], *, full: bool) -> None:
        """Count a full buffer and, with time stamps, the scans it dropped (see the module
        docstring). The scan interval is the mean over every gap-free stretch seen (sums of
        successive differences: the jitter of single stamps cancels), or, before there is
        one, the median interval of the full drain's held scans."""
        stamps = [int(s["in_timestamp"]) for s in scans] if "in_timestamp" in scans[0] else []
        if not stamps:
            self.health.buffer_overflows += full
            self._overflowed = full
            return
        held = stamps[:self._buffer_scans] if full else stamps
        if self._overflowed and self._last_stamp is not None:
            interval = self._mean_interval() or self._interval_ns
            if interval > 0:
                self.health.scans_lost += max(0, round((stamps[0] - self._last_stamp)
                                                       / interval) - 1)
        elif self._last_stamp is not None:
            held = [self._last_stamp, *held]
        if len(held) > 1:
            self._interval_sum_ns += held[-1] - held[0]
            self._interval_count += len(held) - 1
        if full:
            self.health.buffer_overflows += 1
            if len(held) > 2:
                self._interval_ns = statistics.median(b - a for a, b in pairwise(held))
            # scans read after the drain made room may follow a gap
            tail = stamps[len(stamps[:self._buffer_scans]) - 1:]
            interval = self._mean_interval() or self._interval_ns
            if interval > 0:
                self.health.scans_lost += sum(max(0, round((b - a) / interval) - 1)
                                              for a, b in pairwise(tail))
        self._overflowed = full
        self._last_stamp = stamps[-1]

    def _mean_interval(self) -> float:
        return self._interval_sum_ns / self._interval_count if self._interval_count else 0.0

    def _scan_times(self, now_ns: int, scans: list[dict[str, float]]) -> list[int]:
        """Pipeline times of the scans: the kernel's timestamps moved onto the pipeline clock
        by the smallest delay seen between a newest scan and its poll (both clocks are
        monotonic, so that offset only shrinks towards the true one); without timestamps,
        the scans spaced by the sampling period back from the poll."""
        if "in_timestamp" in scans[-1]:
            stamps = [int(s["in_timestamp"]) for s in scans]
            offset = now_ns - stamps[-1]
            if self._ts_offset_ns is None or offset < self._ts_offset_ns:
                self._ts_offset_ns = offset
            times = [ts + self._ts_offset_ns for ts in stamps]
        else:
            step = round(1e9 / self._rate_hz) if self._rate_hz > 0 else 0
            times = [now_ns - (len(scans) - 1 - i) * step for i in range(len(scans))]
        ordered = []
        for t in times:  # never before an earlier sample
            self._last_t_ns = max(t, self._last_t_ns + 1)
            ordered.append(self._last_t_ns)
        return ordered

    def _samples(self, t_ns: int, values: dict[str, list[float]]) -> list[Sample]:
        out: list[Sample] = []
        d = self.device
        if "accel" in values:
            out.append(AccelSample(t_ns=t_ns, device=d, accel_m_s2=tuple(values["accel"])))
        if "anglvel" in values:
            out.append(GyroSample(t_ns=t_ns, device=d, gyro_rad_s=tuple(values["anglvel"])))
        if "magn" in values:
            out.append(MagSample(t_ns=t_ns, device=d, mag_ut=tuple(values["magn"])))
        if "pressure" in values:
            out.append(PressureSample(t_ns=t_ns, device=d, pressure_pa=values["pressure"][0]))
        if "temp" in values:
            out.append(TemperatureSample(t_ns=t_ns, device=d,
                                         temperature_degc=values["temp"][0]))
        return out
