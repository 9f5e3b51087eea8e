"""What every chip driver provides: probe -> configure -> poll, with settings in physical units.

A driver knows its chip's registers and its bus link; it knows nothing about estimators, and
it never knows whether the link ends at silicon or at an emulator. It produces samples in SI
units in the chip's own sensor frame; calibration and mounting are applied by the pipeline.
"""

from __future__ import annotations

import warnings
from abc import ABC, abstractmethod
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any, ClassVar

from pydantic import BaseModel, ConfigDict, model_validator

from imuhal.bus.base import Bus, BusKind, Link
from imuhal.core.blocks import Block, blocks_of
from imuhal.core.clock import Clock
from imuhal.core.errors import ImuhalDeprecationWarning
from imuhal.core.poll_plan import POLL_PLAN
from imuhal.core.samples import Quantity, Sample
from imuhal.core.streams import StreamSpec
from imuhal.drivers.settings import literal_choices


class DriverSettings(BaseModel):
    """Base of every driver's settings: physical values only (``odr_hz: 250``), never codes."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    renamed: ClassVar[dict[str, str]] = {}
    """Old setting name -> current name (docs/writing-a-driver.md, "Naming settings").
    Profiles written with an old name still load, with a DeprecationWarning."""

    @model_validator(mode="before")
    @classmethod
    def _accept_old_names(cls, data: Any) -> Any:
        if not cls.renamed or not isinstance(data, dict):
            return data
        data = dict(data)
        for old, new in cls.renamed.items():
            if old not in data:
                continue
            if new in data:
                raise ValueError(
                    f"{old!r} is the old name of {new!r}; give only {new!r}")
            warnings.warn(
                f"driver setting {old!r} is deprecated: rename it to {new!r}",
                ImuhalDeprecationWarning, stacklevel=2)
            data[new] = data.pop(old)
        return data

    @classmethod
    def choices(cls) -> dict[str, tuple[Any, ...]]:
        """Every enumerable setting and its allowed values: documentation, error messages
        and the generic conformance sweep use it. Literal and Enum fields are found
        automatically; a driver whose values come from a register table adds them."""
        return literal_choices(cls)


@dataclass(frozen=True)
class DeviceIdentity:
    """What probe() found, bound into stored calibration so it is not applied to another chip."""

    driver: str
    bus: str
    address: int
    identity: str
    """The identity evidence, e.g. ``WHO_AM_I=0xB2`` or ``PROM CRC4=0xB``."""
    note: str = ""


@dataclass
class PollResult:
    """Samples produced by one poll and when the driver wants to be polled next (ns)."""

    samples: list[Sample]
    next_poll_ns: int


@dataclass
class BlockPoll:
    """The blocks one poll produced (imuhal.core.blocks: one per stream, frames in time
    order) and when the driver wants to be polled next (ns)."""

    blocks: list[Block]
    next_poll_ns: int


@dataclass
class DeviceHealth:
    """What only the driver can see, reported in the run summary beside the pipeline's own
    counts (samples, flags and bus errors are counted by the pipeline, once)."""

    resets_detected: int = 0
    """Times the driver found its chip had reset on its own (configuration lost)."""
    reconfigurations: int = 0
    """Times the driver reprogrammed its chip (after a reset, a hang, a recovery)."""
    fifo_overflows: int = 0
    """Times the driver found its chip's FIFO overflowed (or corrupt) and reset it: the
    frames it held are lost."""
    not_converted_ns: int = 0
    """A chip whose conversions the driver starts (no output rate of its own): the time its
    schedule of the configured cadence slid (a late poll, a failed convert command), in
    which the chip made no frame (the frame ledger counts those slots apart, not lost)."""
    idle: tuple[int, int] | None = None
    """(the stamp of the latest frame the driver handed out valid, the latest read since):
    an unbroken run of good reads from that frame's read to this one found no new
    measurement (the chip's data-ready bit clear each time), so the chip made none between
    (None: no such read since the latest frame). The frame ledger counts a hung chip's
    slots apart from lost ones from it (imuhal.pipeline.accounting, ``not_measured``)."""
    overrun_ns: int = 0
    """The stamp of the latest frame whose read found that the chip had overwritten a
    measurement unread since the read before (a data-overrun bit, the AK8963's ST1.DOR)."""
    adjacent: tuple[int, int] | None = None
    """(the stamp of the latest frame the driver handed out valid, the stamp of a frame
    after it) when the read that brought the later one proved the chip measured once since
    the earlier one's read: every read between was good and found nothing new, and this one
    found a new measurement without the overrun bit (the AK8963's ST1: DRDY set, DOR clear,
    a bit cleared by every read). The chip made no frame between the two, whatever their
    stamps say: the frame ledger counts any slot between as not measured, not lost
    (``FrameLedger.adjacent``: a hang too short for ``idle`` to prove). None: no such
    read."""
    skipped_ns: int = 0
    """The stamp of the latest frame whose read found a frame of the accounted stream
    overwritten unread since the read before, for a driver whose reads of its chip are its
    own (the MAX2110x's overrun bits) or whose master's copy carries the chip's status (the
    AK8963's ST1.DOR behind the MPU-9250's slave 0): the frame ledger counts at least one
    lost frame before it, whatever the stamps say."""

    def counts(self) -> dict[str, int]:
        return {"resets_detected": self.resets_detected,
                "reconfigurations": self.reconfigurations,
                **({"fifo_overflows": self.fifo_overflows} if self.fifo_overflows else {})}


SettingsInput = DriverSettings | Mapping[str, Any]
"""What a driver is constructed with: its Settings model, or the profile's mapping of them
(validated by the constructor)."""


class Driver(ABC):
    """Base of every chip driver.

    Subclasses set ``name`` (stable, used in profiles), ``description``, ``Settings``,
    ``channels`` and ``bus_kinds``; they implement ``probe``, ``configure`` and ``poll``.
    """

    name: ClassVar[str]
    description: ClassVar[str] = ""
    Settings: ClassVar[type[DriverSettings]]
    channels: ClassVar[tuple[Quantity, ...]]
    bus_kinds: ClassVar[frozenset[BusKind]]
    child_bus_kinds: ClassVar[Mapping[str, BusKind]] = {}
    """The buses ``child_buses()`` provides, by local name, and their kind (any kind: an I2C
    master, an SPI master, a serial port); profiles check devices behind them against it."""
    child_bus_features: ClassVar[Mapping[str, frozenset[str]]] = {}
    """What each child bus offers beyond transfers, by local name: ``AUTO_READ`` (the master
    reads a slave's registers on its own, imuhal.bus.auto_read). Profiles check settings
    that need a feature (``read: auto``) against it."""

    @classmethod
    def child_bus_features_with(cls, child: str,
                                settings: Mapping[str, Any]) -> frozenset[str]:
        """The features of child bus ``child`` for a device with these profile ``settings``
        (raw, as written): ``child_bus_features``, narrowed by a driver whose bus offers a
        feature only in some configurations (the MPU-9250's aux: in master mode)."""
        return frozenset(cls.child_bus_features.get(child, ()))
    calibration_version: ClassVar[int] = 1
    """Bumped when a change to decoding would invalidate stored user calibration."""
    specified_offset: ClassVar[Mapping[Quantity, float]] = {}
    """The largest offset per axis an uncalibrated part may read, by channel, in the
    channel's unit (accelerometer m/s^2, magnetometer uT), as the chip's datasheet (or the
    driver, when none is published) specifies it: what ``imuhal run`` quotes when a device
    has no calibration for that channel (imuhal.calibrate.missing). Empty: not known."""
    poll_plan: int = POLL_PLAN
    """The poll plan this driver follows (imuhal.core.poll_plan): the newest, unless the
    pipeline replays a recording made under an older one (``Board.poll_plan``)."""
    resumes_in_a_row: ClassVar[int] = 1
    """How many bus errors in a row, before a poll completes, the pipeline answers with
    ``resume()`` before the full ``recover()``. Above 1 only for a driver whose every
    ``resume()`` checks by itself that the chip kept its state (its configuration read
    back): the evidence is then as good the fourth time as the first, and at 10 % of
    transfers failing a second failure in a row comes every hundred polls, each a full
    recovery (the MPU-9250's H_RESET: 110 ms on the clock every device shares)."""

    def __init__(self, link: Link, settings: SettingsInput, *, device: str, clock: Clock) -> None:
        if not isinstance(settings, self.Settings):
            settings = self.Settings.model_validate(settings)
        self.link = link
        self.settings = settings
        self.device = device
        self.clock = clock
        self.health = DeviceHealth()
        self.identity: DeviceIdentity | None = None

    @abstractmethod
    def probe(self) -> DeviceIdentity:
        """Check the chip's identity; raise DeviceNotFoundError naming bus, address,
        expected and found identity when it is absent or another chip."""

    @abstractmethod
    def configure(self) -> None:
        """Reset and program the chip from ``settings``; verify what was written."""

    @abstractmethod
    def poll(self, now_ns: int) -> PollResult:
        """Do the work due at ``now_ns`` and return any complete samples.

        Raise BusError when a transfer fails; the pipeline counts it, flags the interval and
        calls ``recover`` before the next poll.
        """

    def poll_blocks(self, now_ns: int) -> BlockPoll:
        """``poll`` with its samples as blocks, what the pipeline calls. The default groups
        the samples of one poll by stream (one device, sample class and frame): a driver
        that reads one reading per poll delivers blocks of one frame, one that reads a FIFO
        gets blocks of every frame it read. A block without a spec gets the stream's from the
        pipeline (the specs it collected at the device's last configuration: ``streams()``
        is not asked per poll, some drivers build their specs on each call). A driver that
        decodes a FIFO into arrays overrides this and never builds the samples."""
        result = self.poll(now_ns)
        if not result.samples:
            return BlockPoll([], result.next_poll_ns)
        return BlockPoll(blocks_of(result.samples), result.next_poll_ns)

    @property
    def builds_blocks(self) -> bool:
        """``poll_blocks`` decodes this driver's polls into blocks itself in its current
        configuration (the pipeline then calls it; otherwise ``poll``, grouping its samples
        as the base class's ``poll_blocks`` does). Default: the class overrides it."""
        return type(self).poll_blocks is not Driver.poll_blocks

    def data_ready(self, edges_ns: Sequence[int]) -> None:
        """The chip's data-ready line (the profile's ``interrupt:``) raised edges at these
        times (ns, the pipeline clock: the kernel's time stamps of the interrupts), oldest
        first, one per sample the chip produced (edges the kernel did not queue filled in),
        whether or not a read follows. A driver that buffers frames (a FIFO) stamps each
        with its edge; the default ignores them (a register read is polled at its edge's
        time already)."""
        return None

    def drain(self, now_ns: int) -> list[Sample]:
        """The run ends at ``now_ns``: the samples the driver read from its chip and still
        holds (frames waiting for their time stamp), stamped as well as it can, so none is
        lost uncounted. No bus transfer. The default: none held."""
        return []

    def start(self, now_ns: int) -> int:
        """Called once after configure(); returns the time of the first poll."""
        return now_ns

    def look_for(self, now_ns: int) -> int | None:
        """One look for a chip that was not found at start-up (an optional device), made in
        the pipeline's poll loop, so it must not hold the other devices up for long: None
        once the chip is found and configured (``identity`` set; the pipeline then starts
        it), else the time of the next step of this look. Raises what ``probe`` and
        ``configure`` raise when the look found nothing (the pipeline looks again a second
        later). The default probes and configures at once: a few transfers for a chip on
        I2C or SPI. A driver whose probe listens (a receiver on a UART, heard at each baud
        rate for a second or more) looks in steps instead."""
        self.identity = self.probe()
        self.configure()
        return None

    def restart(self, *, reset_detected: bool) -> int:
        """Reconfigure the chip mid-run and return the next poll time: after a silent reset
        (``reset_detected``: the configuration read back wrong) or a stuck sensor (it kept
        its configuration but stopped converting). Both are counted in ``health``."""
        if reset_detected:
            self.health.resets_detected += 1
        self.configure()
        self.health.reconfigurations += 1
        return self.start(self.clock.now_ns())

    def resume(self, now_ns: int) -> int | None:
        """Continue after one transfer of ``poll()`` failed, without resetting the chip:
        return the next poll time, or None when only the full ``recover()`` will do.

        The pipeline calls it after a bus error that followed a good poll (a glitch, most
        likely), and calls ``recover()`` instead when the resumed driver fails again before
        a poll completes (after ``resumes_in_a_row`` resumes). A driver resumes only when it
        can tell its chip kept its state (a configuration that still reads back, a
        conversion whose result can be read again) and never so that a wrong value could
        come out valid; a transfer that fails here raises BusError (the pipeline then
        recovers). The default: None (always recover).
        """
        return None

    def recover(self, now_ns: int) -> int:
        """Bring the chip back after a failed poll; returns the next poll time.

        The default re-probes and reconfigures, which also covers a chip that silently reset.
        """
        self.probe()
        self.configure()
        self.health.reconfigurations += 1
        # configure() may have waited on the clock (resets, reloads): start from after it.
        return self.start(max(now_ns, self.clock.now_ns()))

    def streams(self) -> tuple[StreamSpec, ...]:
        """The spec of every stream this driver delivers in its current configuration
        (imuhal.core.streams), derived from the configuration registers it read back from
        the chip at the last ``configure()`` (or ``refresh_streams()``), never from its
        settings. Empty before ``configure()``, and for a driver that declares none (its
        samples are then only checked for NaN/inf)."""
        return ()

    def refresh_streams(self) -> tuple[StreamSpec, ...]:
        """Read the configuration registers again and return the specs they give: what the
        chip runs now. The pipeline does not call it per poll (it costs bus transfers); the
        default, for a driver that keeps no register state, returns ``streams()``."""
        return self.streams()

    def stream(self, channel: Quantity) -> StreamSpec | None:
        """The spec of the stream carrying ``channel``, or None."""
        for spec in self.streams():
            if spec.quantity == channel:
                return spec
        return None

    @property
    def host_paced(self) -> bool:
        """True while the chip measures when the driver commands it (no output rate of its
        own: the MS5611's conversions, a BMP280 in forced mode). A poll of such a device
        that comes late happens as soon as the host is free, and its conversion measures
        the world of then; a chip with an output rate of its own is polled late at the next
        point of its poll grid instead, so the reading keeps its stamp's phase
        (imuhal.pipeline.pipeline, ``Pipeline._on_phase``)."""
        return False

    @property
    def polls_after_instants(self) -> bool:
        """True while its polls sit within a guard (an eighth of a period) after its chip's
        measurement instants, found by a phase search (``PollGrid(track=True)``: a grid that
        creeps earlier until a poll finds nothing new, then retries a guard later), so a
        grid point can also lie just before an instant. A late poll put off to a later
        point of its grid (``Pipeline._on_phase``) then aims a guard after that point:
        just before the instant it would read the frame before, the one the stall left
        unread, a period old. False: where its polls lie after the instants is not known
        (they keep the phase the driver's first reading gave them)."""
        return False

    def accounted_stream(self) -> tuple[Quantity, int] | None:
        """The channel whose frames the pipeline counts (produced, delivered, lost by cause:
        imuhal.pipeline.accounting) and the chip's frame period on it (ns) in the current
        configuration; None: not accounted (a chip without a fixed output period)."""
        return None

    def full_scale(self, channel: Quantity) -> float | None:
        """The largest magnitude (SI) a correct ``channel`` value can have in the current
        configuration: the stream spec's ``full_scale`` (one source of truth). The pipeline
        flags anything beyond it OUT_OF_RANGE. None: not declared (only NaN/inf are then
        caught)."""
        spec = self.stream(channel)
        return None if spec is None else spec.full_scale

    def child_buses(self) -> dict[str, Bus]:
        """Buses this chip exposes to others (an I2C master or bypass, ...), by local name;
        declare each name and kind in ``child_bus_kinds``."""
        return {}

    def describe(self) -> str:
        return f"{self.name} '{self.device}' on {self.link.describe()}"
