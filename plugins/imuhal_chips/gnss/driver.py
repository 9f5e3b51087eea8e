"""GNSS receiver on a UART: NMEA 0183 (pynmea2) or u-blox UBX NAV-PVT (pyubx2).

Probe listens at each baud rate in turn until it sees a sentence or frame with a valid
checksum, and so learns the protocol and the line speed; configure (u-blox receivers) sets
the navigation rate and the messages with UBX CFG-RATE / CFG-MSG and checks each ACK; poll
reads what has arrived, splits it into sentences and frames, decodes them and turns each
navigation epoch into a :class:`PositionSample` and a :class:`VelocitySample`. A recovery
mid-run does probe's and configure's work one step per poll (imuhal_chips.gnss.bringup), so
it never holds the pipeline's thread while the receiver answers.

Timestamps: ``t_ns`` is the measurement epoch on the pipeline clock. The receiver stamps its
epochs in UTC; the driver maps UTC to the pipeline clock with the smallest arrival delay seen
so far, less the receiver's stated output latency (``latency_s``).

Nothing wrong is fused: a sentence or frame with a bad checksum becomes a sample flagged
CRC_ERROR (counted; values NaN where unreadable); an epoch without a fix is flagged STALE;
garbled bytes are counted in ``stats``. A frame whose checksum passed with two bits flipped
(the 8-bit checksums miss some pairs) is caught where the receiver says a thing twice
(gSpeed and velN, velE; NMEA: the position in RMC and GGA, the speed and course in RMC and
VTG, VTG's speed in knots and km/h: CRC_ERROR) or where the epoch cannot follow the last
valid one (its velocity step, its position against the two epochs' velocities, its geoid
separation, its time and date: IMPLAUSIBLE, imuhal_chips.gnss.integrity). The first fix is
valid only once the epochs after it follow it. An epoch with a fix whose time did not
advance past the last one's (a restarted receiver sending its old solution again) or whose
UTC the receiver says is not valid and fully resolved (NAV-PVT's valid flags) is STALE.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from datetime import date, datetime, timezone
from typing import ClassVar, Literal

from pydantic import Field

from imuhal.bus.base import BusKind, Link
from imuhal.core.clock import Clock
from imuhal.core.errors import ConfigurationError, DeviceNotFoundError
from imuhal.core.samples import (
    FixType,
    HeightDatum,
    PositionSample,
    Quantity,
    Sample,
    SampleFlag,
    VelocitySample,
)
from imuhal.core.streams import StreamSpec, TimeSource
from imuhal.drivers.base import (
    DeviceIdentity,
    Driver,
    DriverSettings,
    PollResult,
    SettingsInput,
)
from imuhal.drivers.validity import StepWatch
from imuhal_chips.gnss.bringup import READ_CHUNK, CfgMessage, Configuration, Search
from imuhal_chips.gnss.decode import (
    DecodeError,
    Fragment,
    decode_nmea,
    decode_ubx,
    sentences_disagree,
)
from imuhal_chips.gnss.framing import StreamSplitter
from imuhal_chips.gnss.integrity import Epoch, EpochWatch
from imuhal_chips.gnss.ubx import CFG_MSG, CFG_RATE, NMEA_IDS, UBX_NAV_PVT, cfg_msg, cfg_rate

NMEA_MESSAGES = ("GGA", "RMC", "VTG", "GSA")
DAY_NS = 86_400 * 10**9
FOREIGN_LIMIT = 8
"""Valid sentences of the other protocol in a row that mean the receiver was reset."""
UBX_NAV_PVT_BYTES = 100
NMEA_SENTENCE_BYTES = 75
"""A typical GGA/RMC/VTG/GSA length with CR LF (the line budget in configure)."""
LISTEN_STEP_NS = 20_000_000
"""Probe reads the line at least this often while it listens."""
ACK_POLL_NS = 5_000_000
"""How often configure looks for an ACK: an ACK is 10 bytes, 10 ms at 9600 baud."""
SPEED_SIGMA_M_S = 0.5
"""The speed noise per axis the step check allows for (a u-blox states 0.1-0.5 m/s)."""
UERE_M = 5.0
"""An NMEA receiver's position error per unit of HDOP (the user equivalent range error of a
single-frequency receiver, 4-6 m rms): its horizontal accuracy is HDOP times this."""
NMEA_HDOP_UNKNOWN = 5.0
"""The HDOP taken when an NMEA epoch states none (GSA and GGA lost): a poor fix's."""
DAY_S = 86_400.0
WEEK_S = 7 * DAY_S
STALE_TIME_INVALID = "time not valid"
STALE_TIME_REPEATED = "time not advancing"
QUIET_NS = 100_000_000
"""A line quiet this long (or 2.5 polls) has finished the epoch's burst."""
FROZEN_MOVE_M = (0.05, 0.2)
"""(horizontal, vertical) distance (m) an epoch's velocity must carry the receiver over the
time since the last epoch before a repeat of that epoch's position is impossible: twice the
coarsest resolution a receiver states it in (NMEA's 1e-5 arc minute, 1.85 cm; GGA's
altitude, 0.1 m). Below it a receiver at rest (a u-blox's static hold pins the position and
zeroes the velocity) may repeat itself."""


class GnssSettings(DriverSettings):
    protocol: Literal["auto", "nmea", "ubx"] = "auto"
    """What to decode; ``auto``: whatever probe finds (UBX preferred when both are seen)."""
    baud_rates: tuple[int, ...] = (9600, 38400, 115200, 57600, 4800)
    """Line speeds probe tries, in order (u-blox default: 9600; MTK: 9600 or 38400)."""
    rate_hz: float = Field(1.0, gt=0, le=25)
    """Navigation rate set with CFG-RATE (u-blox) when ``configure_receiver`` (default: the
    factory 1 Hz, which four NMEA sentences fit into at 9600 baud)."""
    messages: tuple[str, ...] | None = None
    """Messages to enable (NMEA names or NAV-PVT); default: NAV-PVT for UBX, GGA RMC VTG GSA
    for NMEA."""
    configure_receiver: bool = True
    """Send UBX CFG messages (u-blox receivers); False leaves the receiver as it is."""
    poll_hz: float = Field(20.0, gt=0, le=200)
    """How often the UART buffer is read."""
    probe_window_s: float = Field(1.5, gt=0)
    """How long probe listens at each baud rate (longer than the slowest output period)."""
    latency_s: float = Field(0.0, ge=0)
    """The receiver's output latency (epoch to first byte), subtracted from arrival times."""
    max_acceleration_m_s2: float = Field(100.0, gt=0)
    """The largest acceleration the vehicle makes (10 g by default: aerobatics); a velocity
    that changed faster since the last plausible epoch is flagged IMPLAUSIBLE, and so is a
    position further from the last valid one advanced by the two epochs' velocities than
    5 sigma of the receiver's stated accuracies and what this acceleration moves the vehicle
    off that path (imuhal_chips.gnss.integrity)."""


@dataclass
class GnssStats:
    sentences: int = 0
    ubx_frames: int = 0
    checksum_errors: int = 0
    decode_errors: int = 0
    garbage_bytes: int = 0
    ubx_resyncs: int = 0
    """UBX frames with an implausible header or a failed checksum, searched past."""
    inconsistent_frames: int = 0
    """NAV-PVT frames whose checksum passed but whose fields disagree, VTG sentences whose
    two speeds disagree, and NMEA epochs whose sentences disagree on what they both say
    (flagged CRC_ERROR like a failed checksum: the 8-bit Fletcher and the 8-bit XOR miss
    some pairs of flipped bits)."""
    frozen_epochs: int = 0
    """Epochs that repeated the last one's position and velocity although that velocity
    moved the receiver (a hung navigation engine; flagged FROZEN)."""
    epochs: int = 0
    stale_epochs: dict[str, int] = field(default_factory=dict)
    """Epochs with a fix flagged STALE by their time, per reason: the receiver said its time
    was not valid (STALE_TIME_INVALID), or the time did not advance (STALE_TIME_REPEATED)."""
    implausible_epochs: dict[str, int] = field(default_factory=dict)
    """Epochs flagged IMPLAUSIBLE by the integrity checks (imuhal_chips.gnss.integrity),
    per rule: horizontal or vertical position against velocity, geoid separation, time,
    date."""
    last_error: str = ""


@dataclass
class _Epoch:
    time_of_day_s: float
    arrival_ns: int
    parts: list[Fragment] = field(default_factory=list)


class GnssDriver(Driver):
    name: ClassVar[str] = "gnss"
    description: ClassVar[str] = "GNSS receiver on a UART (NMEA 0183 or u-blox UBX NAV-PVT)"
    Settings = GnssSettings
    channels: ClassVar[tuple[Quantity, ...]] = (Quantity.POSITION, Quantity.VELOCITY)
    bus_kinds: ClassVar[frozenset[BusKind]] = frozenset({BusKind.SERIAL})

    def __init__(self, link: Link, settings: SettingsInput, *, device: str,
                 clock: Clock) -> None:
        super().__init__(link, settings, device=device, clock=clock)
        self.settings: GnssSettings
        self.protocol: str = ""
        self.baudrate = 0
        self.stats = GnssStats()
        self._splitter = StreamSplitter()
        self._epoch: _Epoch | None = None
        self._offset_ns: int | None = None
        self._prev_height: tuple[int, float] | None = None
        self._last_solution: tuple[int, float, float, float, tuple[float, float, float]] \
            | None = None
        """(t_ns, latitude, longitude, height, NED velocity) of the last epoch with a fix."""
        noise = 6.0 * math.sqrt(2.0) * SPEED_SIGMA_M_S
        self._velocity_watch = tuple(StepWatch(self.settings.max_acceleration_m_s2, noise)
                                     for _ in range(3))
        """Per NED axis: how far the velocity may move between epochs."""
        self.epoch_watch = EpochWatch(self.settings.max_acceleration_m_s2)
        """Position, geoid separation and time against the last valid epoch."""
        self._last_time: tuple[str, float] | None = None
        """The last valid epoch's navigation time: ("week", iTOW s) or ("day", UTC time of
        day s). Kept across a recovery: a restarted receiver's old solution carries the
        old time."""
        self._foreign = 0
        self._last_byte_ns = 0
        self._quiet_ns = max(QUIET_NS, round(2.5e9 / self.settings.poll_hz))
        self._nav_rate_hz: float | None = None
        """The navigation rate the receiver acknowledged (CFG-RATE ACK-ACK), or the
        profile's statement of it when the receiver is not configured."""
        self._step_ns = round(1e9 / self.settings.poll_hz)
        self._search: Search | None = None
        """A recovery's search for the receiver, one step per poll (None: not searching)."""
        self._configuring: Configuration | None = None
        """A recovery's configuration of the receiver, one step per poll."""

    # -- probe ------------------------------------------------------------------------

    def probe(self) -> DeviceIdentity:
        s = self.settings
        try:
            import pynmea2  # noqa: F401
            import pyubx2  # noqa: F401
        except ImportError as exc:
            raise ConfigurationError(f"{self.describe()}: the GNSS driver needs pynmea2 and "
                                     f"pyubx2 ({exc}); install imuhal[gps]") from None
        search = Search(self.link, s.baud_rates, round(s.probe_window_s * 1e9),
                        self.clock.now_ns())
        step = min(round(1e9 / s.poll_hz), LISTEN_STEP_NS)
        while (found := search.step(self.clock.now_ns())) == "":
            self.clock.sleep_until(min(search.end_ns, self.clock.now_ns() + step))
        return self._heard(search, found)

    def _heard(self, search: Search, found: str | None) -> DeviceIdentity:
        """What ``search`` ended with: the receiver's identity, or DeviceNotFoundError."""
        s = self.settings
        bus = self.link.bus
        if found is None:
            raise DeviceNotFoundError(
                driver=self.name, bus=bus.name, address=self.link.target,
                expected=f"NMEA or UBX with valid checksums at one of {list(s.baud_rates)} "
                         "baud",
                found="; ".join(search.seen),
                hint="check the receiver's TX goes to the host's RX, its power, and that its "
                     "baud rate is in settings.baud_rates")
        # A u-blox receiver heard speaking NMEA is switched to UBX by configure().
        self.protocol = found if s.protocol == "auto" else s.protocol
        self.baudrate = search.baud
        self.identity = DeviceIdentity(self.name, bus.name, self.link.target,
                                       f"{found.upper()} at {search.baud} baud")
        return self.identity

    # -- configure ----------------------------------------------------------------------

    def configure(self) -> None:
        if not self.protocol:
            raise ConfigurationError(f"{self.describe()}: configure() before probe()")
        self._splitter = StreamSplitter()
        self._epoch = None
        self._foreign = 0
        if not self.settings.configure_receiver:
            # nothing to ask the receiver: the profile states its rate
            self._nav_rate_hz = self.settings.rate_hz
            return
        configuration = self._configuration()
        self._nav_rate_hz = None
        while not configuration.step(self.clock.now_ns()):
            self.clock.sleep_until(self.clock.now_ns() + ACK_POLL_NS)
        # every message acknowledged, the rate last (ACK-ACK)
        self._nav_rate_hz = self.settings.rate_hz

    def _configuration(self) -> Configuration:
        """The CFG messages that make the receiver send what the settings ask, in order;
        ConfigurationError for messages the driver does not know or more than the line
        carries."""
        s = self.settings
        wanted = set(s.messages or (("NAV-PVT",) if self.protocol == "ubx" else NMEA_MESSAGES))
        unknown = wanted - set(NMEA_IDS) - {"NAV-PVT"}
        if unknown:
            raise ConfigurationError(
                f"{self.describe()}: cannot enable {sorted(unknown)}; known messages: "
                f"NAV-PVT, {', '.join(NMEA_IDS)}")
        need = (UBX_NAV_PVT_BYTES * ("NAV-PVT" in wanted)
                + NMEA_SENTENCE_BYTES * len(wanted - {"NAV-PVT"})) * s.rate_hz
        line = self.baudrate / 10 if self.baudrate else math.inf
        if need > line:
            raise ConfigurationError(
                f"{self.describe()}: {', '.join(sorted(wanted))} at {s.rate_hz:g} Hz need "
                f"about {need:.0f} bytes/s, but {self.baudrate} baud carries {line:.0f}; "
                "lower rate_hz, enable fewer messages, or set the receiver to a faster baud "
                "rate")
        # On first, then off, then the rate: every state on the way (and the half-configured
        # state a failed attempt leaves for bring_up's retry) carries at most the factory
        # output plus the wanted one at the factory 1 Hz (under 600 bytes/s, within even
        # 9600 baud), and is never silent, so a retry's probe still hears the receiver
        # (turning the factory messages off first left a receiver that said nothing after
        # a CFG write failed there: "nothing received", once in 40 start-ups at 1 % line
        # noise). Raising the rate first meant 5 Hz of NAV-PVT plus the factory NMEA: 2000
        # bytes/s on a 960 bytes/s line, a backlog that held every later ACK back.
        messages = {"NAV-PVT": UBX_NAV_PVT, **NMEA_IDS}
        steps = [CfgMessage(cfg_msg(cls, mid, int(enable)), CFG_MSG, f"CFG-MSG {name}")
                 for enable in (True, False)
                 for name, (cls, mid) in messages.items() if (name in wanted) == enable]
        steps.append(CfgMessage(cfg_rate(s.rate_hz), CFG_RATE, f"CFG-RATE {s.rate_hz:g} Hz"))
        return Configuration(self.link, self._splitter, steps, self.describe())

    def streams(self) -> tuple[StreamSpec, ...]:
        """Position (deg, deg, m) and NED velocity (m/s) at the navigation rate the
        receiver acknowledged (CFG-RATE, answered ACK-ACK; with ``configure_receiver:
        false``, the profile's ``rate_hz``, which nothing can check), stamped with the
        receiver's epochs. No scale (a solution, not counts) and no full scale. While a
        recovery reconfigures the receiver they stay those of its start-up: it delivers
        nothing meanwhile, and the recovery ends acknowledged at the same rate or in an
        error."""
        rate_hz = self._nav_rate_hz
        if rate_hz is None:
            return ()
        latency_s = self.settings.latency_s
        return tuple(StreamSpec(self.device, quantity, None, rate_hz, latency_s=latency_s,
                                time_source=TimeSource.RECEIVER_EPOCH)
                     for quantity in (Quantity.POSITION, Quantity.VELOCITY))

    # -- recovery -----------------------------------------------------------------------

    def recover(self, now_ns: int) -> int:
        """Find and reconfigure the receiver again without waiting on the clock: each of
        the device's next polls takes one step (listen at a baud rate, send a CFG message,
        look for its ACK) and returns at once, so the pipeline polls the other devices
        between them (imuhal_chips.gnss.bringup). A step that fails raises what probe and
        configure raise, and the pipeline recovers the device again. The epochs after it
        are held like a first fix (``EpochWatch.restart``)."""
        s = self.settings
        self._epoch = None
        self._foreign = 0
        self._configuring = None
        self.epoch_watch.restart()
        self._search = Search(self.link, s.baud_rates, round(s.probe_window_s * 1e9), now_ns)
        return now_ns + self._step_ns

    def resume(self, now_ns: int) -> int | None:
        """Carry on after the port failed a read or a write: a UART keeps no state in the
        receiver that a failed call could change. A failed read costs the bytes it carried
        (the checksums catch a sentence or frame cut by it), a failed CFG write counts as a
        send whose ACK did not come; a search or configuration under way goes on where it
        was. A receiver that did restart is found by what it sends (factory NMEA where UBX
        was configured), and a port that keeps failing gets the full recovery (the
        pipeline's rule: a second failure before a poll completes)."""
        return now_ns + (ACK_POLL_NS if self._configuring is not None else self._step_ns)

    def look_for(self, now_ns: int) -> int | None:
        """A receiver not found at start-up is looked for in the steps a recovery takes
        (listen at each baud rate, send each CFG message, look for its ACK), one per call,
        so the other devices are polled between them: the probe's blocking search would
        hold the whole board for up to a window per baud rate, twice."""
        if self._search is None and self._configuring is None:
            self._epoch = None
            self._foreign = 0
            self._search = Search(self.link, self.settings.baud_rates,
                                  round(self.settings.probe_window_s * 1e9), now_ns)
        try:
            next_ns = self._bring_up_step(now_ns)
        except Exception:
            self._search = self._configuring = None  # the next look starts afresh
            raise
        if next_ns is None:
            self._nav_rate_hz = self.settings.rate_hz  # acknowledged, or stated by the profile
        return next_ns

    def _recovery_step(self, now_ns: int) -> int:
        """One step of the recovery ``recover`` started; the time of the next poll."""
        next_ns = self._bring_up_step(now_ns)
        if next_ns is not None:
            return next_ns
        self.health.reconfigurations += 1
        return now_ns + self._step_ns

    def _bring_up_step(self, now_ns: int) -> int | None:
        """One step of a search and configuration under way: the time of the next, or None
        once the receiver is found and configured. DeviceNotFoundError when the search
        heard nothing valid at any baud rate."""
        if self._search is not None:
            found = self._search.step(now_ns)
            if found == "":
                return min(self._search.end_ns, now_ns + self._step_ns)
            search, self._search = self._search, None
            self._heard(search, found)
            self._splitter = StreamSplitter()
            if self.settings.configure_receiver:
                self._configuring = self._configuration()
        if self._configuring is not None and not self._configuring.step(now_ns):
            return now_ns + ACK_POLL_NS
        self._configuring = None
        return None

    # -- poll ---------------------------------------------------------------------------

    def poll(self, now_ns: int) -> PollResult:
        if self._search is not None or self._configuring is not None:
            return PollResult([], self._recovery_step(now_ns))
        data = self.link.receive(READ_CHUNK)
        splitter = self._splitter
        before = splitter.garbage_bytes, splitter.resyncs
        items = splitter.feed(data)
        self.stats.garbage_bytes += splitter.garbage_bytes - before[0]
        self.stats.ubx_resyncs += splitter.resyncs - before[1]
        samples: list[Sample] = []
        for (kind, item), first_byte_ns in zip(items, self._first_bytes(items, now_ns),
                                               strict=True):
            samples += self._take(kind, item, now_ns, first_byte_ns)
        if data:
            self._last_byte_ns = now_ns
        if self._epoch is not None and (self._epoch_complete() or
                                        now_ns - self._last_byte_ns >= self._quiet_ns):
            # At 9600 baud an epoch's burst spans several reads: it is complete when every
            # configured message has come, or when the line has been quiet for a while.
            samples += self._close_epoch()
        return PollResult(samples, now_ns + round(1e9 / self.settings.poll_hz))

    def _first_bytes(self, items: list[tuple[str, bytes]], now_ns: int) -> list[int]:
        """The latest each item's first byte can have arrived (pipeline clock, ns): the read
        happened at the clock's time, not at the poll's due time (a poll made late, when
        another device held the thread, reads what came meanwhile), and after the item came
        itself and everything read after it (the items after it, the incomplete tail), at
        the line rate. A bound from above: the epoch delays taken from it never fall below
        the true one, so their minimum (the time mapping) stays right. Stamped at the due
        time, the read of three epochs after a 0.4 s stall lowered that minimum by 0.4 s,
        and every later epoch was stamped 0.4 s early (issue 26: valid velocities up to
        2 m/s off the truth at their time stamps in a turn)."""
        if not items:
            return []
        read_ns = max(now_ns, self.clock.now_ns())
        byte_ns = 10e9 / self.baudrate if self.baudrate else 0.0
        after = len(self._splitter.buffer)
        out = []
        for _, item in reversed(items):
            after += len(item)
            out.append(read_ns - round(after * byte_ns))
        out.reverse()
        return out

    def _expected(self) -> set[str] | None:
        s = self.settings
        if not s.configure_receiver:
            return None  # what the receiver sends is its own business: wait for quiet
        return set(s.messages or (("NAV-PVT",) if self.protocol == "ubx" else NMEA_MESSAGES))

    def _epoch_complete(self) -> bool:
        expected = self._expected()
        return self._epoch is not None and expected is not None and \
            expected <= {p.kind for p in self._epoch.parts}

    def _take(self, kind: str, item: bytes, now_ns: int, first_byte_ns: int) -> list[Sample]:
        if kind == "nmea":
            self.stats.sentences += 1
        else:
            self.stats.ubx_frames += 1
        try:
            frag = decode_nmea(item) if kind == "nmea" else decode_ubx(item)
        except DecodeError as exc:
            self.stats.decode_errors += 1
            self.stats.last_error = str(exc)
            return []
        if not frag.checksum_ok:
            if frag.inconsistent:
                self.stats.inconsistent_frames += 1
                self.stats.last_error = frag.inconsistent
            else:
                self.stats.checksum_errors += 1
            return [self._flagged(frag, now_ns)]
        if frag.kind not in ("GGA", "RMC", "VTG", "GSA", "NAV-PVT"):
            return []
        if self.protocol == "ubx" and kind == "nmea":
            # A receiver configured for UBX that talks NMEA has restarted with its factory
            # settings: the pipeline's recovery re-probes and reconfigures it.
            self._foreign += 1
            if self._foreign >= FOREIGN_LIMIT and self.settings.configure_receiver:
                self._foreign = 0
                self.health.resets_detected += 1
                raise ConfigurationError(f"{self.describe()}: the receiver sends NMEA although "
                                         "configured for UBX (it restarted); reconfiguring")
            return []
        if self.protocol == "nmea" and kind == "ubx":
            return []
        self._foreign = 0
        out: list[Sample] = []
        if frag.time_of_day_s is not None:
            if self._epoch is not None and \
                    abs(self._epoch.time_of_day_s - frag.time_of_day_s) > 1e-3:
                out += self._close_epoch()
            if self._epoch is None:
                self._epoch = _Epoch(frag.time_of_day_s, first_byte_ns)
        if self._epoch is not None:
            self._epoch.parts.append(frag)
        return out

    def _flagged(self, frag: Fragment, now_ns: int) -> PositionSample:
        nan = math.nan
        return PositionSample(
            t_ns=now_ns, device=self.device, flags=SampleFlag.CRC_ERROR,
            latitude_deg=nan if frag.latitude_deg is None else frag.latitude_deg,
            longitude_deg=nan if frag.longitude_deg is None else frag.longitude_deg,
            height_m=nan if frag.height_msl_m is None else frag.height_msl_m)

    def _epoch_time_ns(self, epoch: _Epoch) -> tuple[int, int]:
        """The epoch on the pipeline clock: UTC time of day plus the smallest delay (arrival
        minus UTC, modulo a day) seen so far, this epoch's included, less the stated output
        latency; and that smallest delay, which the caller keeps (``_offset_ns``) only when
        the epoch's time can be trusted: a UTC time a flip moved 128 s ahead would have
        stamped every later epoch 128 s early."""
        tod_ns = round(epoch.time_of_day_s * 1e9)
        delay = (epoch.arrival_ns - tod_ns) % DAY_NS
        offset = delay if self._offset_ns is None else min(self._offset_ns, delay)
        t_ns = epoch.arrival_ns - delay + offset - round(self.settings.latency_s * 1e9)
        return t_ns, offset

    def _close_epoch(self) -> list[Sample]:
        epoch, self._epoch = self._epoch, None
        if epoch is None:
            return []
        merged = _merge(epoch.parts)
        self.stats.epochs += 1
        t_ns, offset_ns = self._epoch_time_ns(epoch)
        disagreement = sentences_disagree(epoch.parts)
        if disagreement:
            # which sentence was hit cannot be told: the epoch is no fix and no reference
            self.stats.inconsistent_frames += 1
            self.stats.last_error = disagreement
            return [self._flagged(merged, t_ns)]
        fix = merged.fix_type if merged.fix_type is not None else FixType.NO_FIX
        has_fix = fix in (FixType.FIX_2D, FixType.FIX_3D, FixType.GNSS_DEAD_RECKONING)
        out: list[Sample] = []
        if merged.latitude_deg is None or merged.longitude_deg is None:
            self._offset_ns = offset_ns  # nothing to check the time against
            if not has_fix:
                out.append(PositionSample(t_ns=t_ns, device=self.device,
                                          flags=SampleFlag.STALE, latitude_deg=math.nan,
                                          longitude_deg=math.nan, height_m=math.nan,
                                          fix_type=fix, satellites=merged.satellites or 0))
            return out
        height = merged.height_msl_m
        velocity = merged.velocity_ned_m_s
        if velocity is None:
            velocity = self._nmea_velocity(merged, t_ns)
        stale, navigation_time = self._stale_time(merged, epoch)
        if stale and has_fix:
            # no new solution, or none the driver can place in time: not fused, no reference
            # for the checks, and its time does not move the UTC-to-clock mapping
            self.stats.stale_epochs[stale] = self.stats.stale_epochs.get(stale, 0) + 1
            self.stats.last_error = stale
            step = SampleFlag.STALE
        else:
            step = self._epoch_checks(merged, epoch, t_ns, has_fix, height, velocity)
            if has_fix and not step:
                # Only a valid epoch's time: a flip the time rule refuses (iTOW 2.3 h ahead)
                # would have made every honest epoch after it "not advancing".
                self._last_time = navigation_time
        if velocity is not None and has_fix:
            # Before the position: a consumer of the fix then has the same epoch's velocity.
            out.append(VelocitySample(t_ns=t_ns, device=self.device, flags=step,
                                      velocity_ned_m_s=velocity,
                                      accuracy_m_s=merged.speed_accuracy_m_s))
        if not step:
            self._offset_ns = offset_ns
        flags = (SampleFlag.OK if has_fix and height is not None else SampleFlag.STALE) | step
        out.append(PositionSample(
            t_ns=t_ns, device=self.device, flags=flags,
            latitude_deg=merged.latitude_deg, longitude_deg=merged.longitude_deg,
            height_m=math.nan if height is None else height, height_datum=HeightDatum.MSL,
            horizontal_accuracy_m=merged.horizontal_accuracy_m,
            vertical_accuracy_m=merged.vertical_accuracy_m,
            fix_type=fix, satellites=merged.satellites or 0,
            utc_s=_utc_s(merged.day, epoch.time_of_day_s)))
        return out

    def _stale_time(self, merged: Fragment, epoch: _Epoch) -> tuple[str, tuple[str, float]]:
        """Why an epoch is no new solution by its own time, or '', and its navigation time
        (("week", iTOW s) for UBX, which a flip in the UTC fields leaves alone; ("day", UTC
        time of day s) for NMEA). Stale: the receiver says its UTC is not valid and fully
        resolved (NAV-PVT's validDate, validTime, fullyResolved: its time, and so the
        epoch's time stamp, may be seconds off), or the time did not advance past the last
        valid epoch's (a receiver restarted with its last solution in battery-backed memory
        and sending it again, or a stale replay). Navigation time never runs back (a week's
        or a day's wrap aside)."""
        if merged.gps_time_of_week_s is not None:
            now = ("week", merged.gps_time_of_week_s)
        else:
            now = ("day", epoch.time_of_day_s)
        if merged.time_valid is False:
            return STALE_TIME_INVALID, now
        last = self._last_time
        if last is not None and last[0] == now[0]:
            period = WEEK_S if now[0] == "week" else DAY_S
            if not 0.0 < (now[1] - last[1]) % period < period / 2.0:
                return STALE_TIME_REPEATED, now
        return "", now

    def _epoch_checks(self, merged: Fragment, epoch: _Epoch, t_ns: int, has_fix: bool,
                      height_m: float | None,
                      velocity: tuple[float, float, float] | None) -> SampleFlag:
        """The flags an epoch with a fix earns before it is handed out: FROZEN when it
        repeats the last solution although it moved, IMPLAUSIBLE when its velocity steps or
        its position strays from where the last valid epoch's velocity carried it."""
        step = SampleFlag.OK
        if velocity is not None and has_fix:
            step = self._repeated(merged, velocity, t_ns)
            if not step:
                step = self._velocity_step(velocity, t_ns)
        if has_fix and height_m is not None and not step:
            # an epoch whose velocity cannot be right came from a frame hit on the line (or a
            # hung receiver): it is not held against the position, which is not trusted either
            step = self._position_check(merged, epoch, t_ns, height_m, velocity)
        return step

    def _repeated(self, merged: Fragment, velocity: tuple[float, float, float],
                  t_ns: int) -> SampleFlag:
        """FROZEN when the epoch repeats the last one's position and velocity exactly
        although that velocity carried the receiver more than FROZEN_MOVE_M since it: the
        receiver's navigation engine hung and it sends its last solution with each new
        epoch's time (the emulator's ``frozen`` fault). A working receiver's position moves
        with its velocity, and its velocity noise never repeats a moving triple to the mm/s.
        A repeated epoch is no new reference for the velocity step check."""
        position = (merged.latitude_deg or 0.0, merged.longitude_deg or 0.0,
                    merged.height_msl_m if merged.height_msl_m is not None else math.nan)
        last, self._last_solution = self._last_solution, (t_ns, *position, velocity)
        if last is None or t_ns <= last[0] or last[1:] != (*position, velocity):
            return SampleFlag.OK
        dt_s = (t_ns - last[0]) / 1e9
        horizontal_m = math.hypot(velocity[0], velocity[1]) * dt_s
        if horizontal_m <= FROZEN_MOVE_M[0] and abs(velocity[2]) * dt_s <= FROZEN_MOVE_M[1]:
            return SampleFlag.OK
        self.stats.frozen_epochs += 1
        return SampleFlag.FROZEN

    def _velocity_step(self, velocity: tuple[float, float, float], t_ns: int) -> SampleFlag:
        """IMPLAUSIBLE when an axis of ``velocity`` (NED) lies further from the last
        plausible one than ``max_acceleration_m_s2`` moves it in the time between them, plus
        6 sigma of two epochs' noise at 0.5 m/s per axis (imuhal.drivers.validity.StepWatch:
        three refused epochs that agree are a new level). A NAV-PVT can pass its 8-bit
        Fletcher checksum with velD 32.8 m/s off (two flips of bit 7, issue 26), which
        nothing else in the frame repeats."""
        flags = SampleFlag.OK
        for watch, value in zip(self._velocity_watch, velocity, strict=True):
            flags |= watch.observe(t_ns, value)
        return flags

    def _position_check(self, merged: Fragment, epoch: _Epoch, t_ns: int, height_m: float,
                        velocity: tuple[float, float, float] | None) -> SampleFlag:
        """IMPLAUSIBLE when the epoch's position, geoid separation or time cannot follow the
        last valid epoch's (imuhal_chips.gnss.integrity: a pair of flipped bits the 8-bit
        checksum misses, issue 26); counted per rule in ``stats.implausible_epochs``. NMEA
        states no accuracies: its horizontal one is HDOP times ``UERE_M``, and its vertical
        velocity (made from the heights) checks nothing."""
        assert merged.latitude_deg is not None and merged.longitude_deg is not None
        ubx = merged.velocity_ned_m_s is not None
        h_acc = merged.horizontal_accuracy_m
        if h_acc is None:
            h_acc = (merged.hdop if merged.hdop is not None else NMEA_HDOP_UNKNOWN) * UERE_M
        gps_minus_utc = None
        if merged.gps_time_of_week_s is not None:
            gps_minus_utc = (merged.gps_time_of_week_s - epoch.time_of_day_s) % DAY_S
        verdict = self.epoch_watch.observe(Epoch(
            t_ns=t_ns, latitude_deg=merged.latitude_deg, longitude_deg=merged.longitude_deg,
            height_msl_m=height_m, velocity_ned_m_s=velocity, horizontal_accuracy_m=h_acc,
            vertical_accuracy_m=merged.vertical_accuracy_m,
            speed_accuracy_m_s=(merged.speed_accuracy_m_s
                                if merged.speed_accuracy_m_s is not None else SPEED_SIGMA_M_S),
            vertical_velocity_measured=ubx, height_ellipsoid_m=merged.height_ellipsoid_m,
            gps_minus_utc_s=gps_minus_utc,
            utc_day=None if merged.day is None else merged.day.toordinal()))
        if verdict.ok:
            return SampleFlag.OK
        self.stats.implausible_epochs[verdict.reason] = \
            self.stats.implausible_epochs.get(verdict.reason, 0) + 1
        self.stats.last_error = verdict.reason if not verdict.ratios else \
            f"{verdict.reason} beyond its bound ({max(r for _, r in verdict.ratios):.3g} x)"
        return SampleFlag.IMPLAUSIBLE

    def _nmea_velocity(self, merged: Fragment,
                       t_ns: int) -> tuple[float, float, float] | None:
        """NED velocity (m/s) from NMEA's ground speed and course; NMEA has no vertical
        velocity: it is the change of the GGA height between consecutive epochs (what
        NMEA-only flight apps do). None without the parts or before the second epoch."""
        height = merged.height_msl_m
        if merged.ground_speed_m_s is None or merged.course_deg is None or height is None:
            return None
        prev, self._prev_height = self._prev_height, (t_ns, height)
        if prev is None or t_ns <= prev[0]:
            return None
        down = -(height - prev[1]) / ((t_ns - prev[0]) / 1e9)
        c = math.radians(merged.course_deg)
        g = merged.ground_speed_m_s
        return (g * math.cos(c), g * math.sin(c), down)

    def start(self, now_ns: int) -> int:
        return now_ns


MERGED_FIELDS = ("day", "latitude_deg", "longitude_deg", "height_msl_m", "height_ellipsoid_m",
                 "gps_time_of_week_s", "satellites", "hdop",
                 "ground_speed_m_s", "course_deg", "velocity_ned_m_s", "horizontal_accuracy_m",
                 "vertical_accuracy_m", "speed_accuracy_m_s", "time_valid")
"""The fragment fields an epoch takes from its sentences or messages (a later one wins)."""


def _merge(parts: list[Fragment]) -> Fragment:
    """One fragment holding what an epoch's parts said."""
    merged = Fragment(kind="epoch")
    for part in parts:
        for name in MERGED_FIELDS:
            value = getattr(part, name)
            if value is not None:
                setattr(merged, name, value)
        # GGA says fix or not, GSA says 2D or 3D: the more specific one wins.
        if part.fix_type is not None and (merged.fix_type is None
                                          or part.kind in ("GSA", "NAV-PVT")):
            merged.fix_type = part.fix_type
    return merged


def _utc_s(day: date | None, time_of_day_s: float) -> float | None:
    if day is None:
        return None
    midnight = datetime(day.year, day.month, day.day, tzinfo=timezone.utc)
    return midnight.timestamp() + time_of_day_s
