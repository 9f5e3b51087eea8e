"""The pipeline: one clock, every device polled when it asks to be, every sample through the
same steps, estimators fed only valid body-frame samples, sinks fed everything.

Embedding: ``Pipeline.open(profile, registry)`` (the profile's real buses) or
``imuhal.emulation.open_emulated(profile, registry, scenario="thermal")`` (an emulated board),
then iterate ``pipeline.events(duration_s)`` (samples and estimates in time order),
``pipeline.blocks(duration_s)`` (the same with each FIFO read as its blocks, no sample built
per frame) or call ``pipeline.run(duration_s, sinks)``. The pipeline sees a board only through
:class:`~imuhal.pipeline.board.Board`; it knows nothing of simulation.
"""

from __future__ import annotations

import heapq
import time
from collections import Counter
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass, field
from typing import Any, cast

import numpy as np

from imuhal.bus.base import Bus, Link
from imuhal.bus.contained import ContainedBus
from imuhal.bus.recording.recorder import BusRecorder
from imuhal.bus.spy import SpyBus, Transfer
from imuhal.calibration.accel_in_flight import AccelOffsetLearner
from imuhal.calibration.hard_iron import HardIronLearner
from imuhal.calibration.model import (
    AccelInFlightSettings,
    CalibrationBinding,
    DeviceCalibration,
    MagInFlightSettings,
    now,
)
from imuhal.core.blocks import Block, blocks_of, interleaved
from imuhal.core.clock import Clock
from imuhal.core.conventions import get_convention
from imuhal.core.errors import BusError, ImuhalError, PluginError, ProfileError, RunEnded
from imuhal.core.frames import FloatArray
from imuhal.core.gaps import StreamGap
from imuhal.core.poll_plan import LATE_RETRY_PLAN, POLL_PLAN
from imuhal.core.samples import GyroSample, MagSample, Quantity, Sample, SampleFlag
from imuhal.core.streams import StreamSpec, TimeSource
from imuhal.drivers.base import DeviceIdentity, Driver
from imuhal.estimation.framed import FramedEvent, express
from imuhal.estimation.outputs import AttitudeBlock, Estimate, rows_of
from imuhal.estimation.streams import StreamContradiction
from imuhal.pipeline.accounting import FrameLedger, Loss, describe_frames
from imuhal.pipeline.board import Board, open_hardware_board
from imuhal.pipeline.bringup import bring_up
from imuhal.pipeline.containment import (
    ContainedSinks,
    Containment,
    DriverDeadline,
    DriverTiming,
    EstimatorGuard,
    PluginFaults,
    Watchdog,
    describe_exception,
    driver_deadline_s,
    driver_timing,
)
from imuhal.pipeline.crosscheck import VerticalCrossCheck
from imuhal.pipeline.learning import AccelTeacher, learned_by_default, learning_settings
from imuhal.pipeline.processing import (
    calibrate_block,
    calibrate_to_body,
    validity_block,
    validity_flags,
)
from imuhal.pipeline.router import Route, Router
from imuhal.pipeline.startup import GyroStartupStage, StartupMeasurement, startup_settings
from imuhal.pipeline.triggers import (
    ClockWaiter,
    LineTrigger,
    RecordedWaiter,
    TimerTrigger,
    TriggerEdge,
    TriggerLine,
    Waiter,
    describe_trigger,
)
from imuhal.plugins.manager import Registry, plugin_origin
from imuhal.profile.model import BoardProfile, InterruptConfig
from imuhal.profile.topology import chip_to_body_rotations, device_order, split_bus_ref
from imuhal.sinks.base import Event, Sink

RECOVERY_BACKOFF_NS = 100_000_000
"""After failed recoveries, wait at most this long before trying the device again (100 ms)."""
RETRY_FIRST_NS = 2_000_000
"""The first retry after a failed recovery comes 2 ms later; each further one waits twice
as long, up to RECOVERY_BACKOFF_NS."""
REPORT_AFTER_FAILURES = 4
"""Consecutive failed recoveries (about 30 ms of trying) before the run reports the device."""
JOIN_RETRY_NS = 1_000_000_000
"""An optional device that is not there is looked for again every second."""
AIM_FROM_FRAME_PERIODS = 6
"""A put-off poll of a driver searching its chip's instants aims from its latest frame's
phase within this many frame periods of it (``Pipeline._on_phase``): a chip clock 2 % off
moves its instants by 0.12 period over them, less than the guard (1/8) the aim adds."""
PUT_OFF_AT_MOST = 3
"""Times in a row a late poll is put off to the next point of its device's grid
(``Pipeline._on_phase``) before it is made when it comes, off the chip's phase."""
NEVER_NS = 1 << 62
"""The next poll of an isolated device: never in any run."""


CLIPPED = SampleFlag.SATURATED | SampleFlag.OUT_OF_RANGE | SampleFlag.FILTER_SETTLING
"""The flags a reading the chip cut at its full scale may carry: SATURATED (the driver saw
the word at its rail), and OUT_OF_RANGE with it (beyond the declared range), and
FILTER_SETTLING (the clips before it are still in the chip's low-pass memory: a rail word
is still at least full scale). OUT_OF_RANGE alone is no clip: a word beyond the range but
not at the rail is a corrupt reading."""


@dataclass
class DeviceRuntime:
    """One device as the pipeline runs it. The pipeline owns every sample, flag and bus
    error count; the driver's ``health`` holds what only the driver can see (resets it
    detected, reconfigurations)."""

    name: str
    driver: Driver
    chip_to_body: FloatArray
    calibration: DeviceCalibration | None
    required: bool = True
    present: bool = False
    """Probed and configured: polled. False: an optional device not (yet) found."""
    needs_recovery: bool = False
    resumed: int = 0
    """Resumes after bus errors since the driver last completed a poll (0: it did): one
    more bus error gets the full recovery once the driver's ``resumes_in_a_row`` are
    spent."""
    next_poll_ns: int = 0
    device_errors: int = 0
    bus_errors: int = 0
    failures: int = 0
    """Consecutive failed recoveries (0 while the device works)."""
    failing_since_ns: int = 0
    warned: set[str] = field(default_factory=set)
    samples: int = 0
    flagged: Counter[str] = field(default_factory=Counter)
    full_scale: dict[Quantity, float | None] = field(default_factory=dict)
    streams: tuple[StreamSpec, ...] = ()
    """The driver's stream specs as read back at the last (re)configuration."""
    deadline_s: float = field(default_factory=lambda: driver_deadline_s(()))
    """How long one call of its driver may take (``driver_deadline_s`` of ``streams``,
    kept with them: it is armed around every poll)."""
    spec_of: dict[Quantity, StreamSpec] = field(default_factory=dict)
    """``streams`` by quantity (the spec a block without one was taken with)."""
    last_valid_ns: dict[Quantity, int] = field(default_factory=dict)
    """Per quantity, the time of the last valid sample (samples must not go back)."""
    chip_to_body_rows: list[list[float]] = field(default_factory=list)
    """``chip_to_body`` as nested lists of floats (every sample is rotated with it)."""
    chip_to_body_array: FloatArray = field(default_factory=lambda: np.eye(3))
    """``chip_to_body`` as a float64 array (every block of several frames is rotated with
    it)."""
    ledger: FrameLedger | None = None
    """Frames produced, delivered and lost by cause (None: the driver accounts for none)."""
    reconfigurations_seen: int = 0
    """The driver's reconfiguration count the ledger last saw."""
    fifo_overflows_seen: int = 0
    """The driver's FIFO overflow count the ledger last saw."""
    not_converted_seen_ns: int = 0
    """The driver's slid schedule time the ledger last saw."""
    idle_seen: tuple[int, int] | None = None
    """The driver's idle reads the ledger last saw."""
    overrun_seen_ns: int = 0
    skipped_seen_ns: int = 0
    """The driver's overrun stamp the ledger last saw."""
    adjacent_seen: tuple[int, int] | None = None
    """The driver's pair of frames proved adjacent the ledger last saw."""
    mag_learner: HardIronLearner | None = None
    """Learning the hard iron in flight (``mag_in_flight``, no stored magnetometer record)."""
    accel_teacher: AccelTeacher | None = None
    """Learning the accelerometer's offset in flight (``accel_in_flight``, no stored
    accelerometer record)."""
    own_blocks: bool = False
    """The driver builds its own blocks (overrides ``Driver.poll_blocks``)."""
    trigger: TimerTrigger | LineTrigger = field(default_factory=TimerTrigger)
    """What says when the device is read (imuhal.pipeline.triggers): its poll grid, or
    the data-ready line its profile names."""
    buffered: bool = False
    """Its chip buffers frames the host reads late (a stream stamped on the chip's clock
    from a FIFO): a late read is then no loss (``Pipeline._note_late``)."""
    edges_ns: list[int] = field(default_factory=list)
    """Data-ready edges taken since the driver's last poll, handed to it at the next
    (``Driver.data_ready``, within the driver's containment)."""
    isolated: bool = False
    """Its driver overran a call's deadline or kept failing: never polled again."""
    put_off: int = 0
    """How many times in a row its pending poll was put off to the next point of its grid
    (``Pipeline._on_phase``); at PUT_OFF_AT_MOST it happens when it comes, late or not."""
    aim_offset_ns: int = 0
    """What the latest put-off added to the phase it aimed at (``Pipeline._aim``): its
    polls are counted that much before they are made."""

    def __post_init__(self) -> None:
        self.chip_to_body_array = np.array(self.chip_to_body, dtype=np.float64)
        self.chip_to_body_rows = self.chip_to_body_array.tolist()
        self.own_blocks = type(self.driver).poll_blocks is not Driver.poll_blocks


EstimatorRuntime = Route
"""One estimator as the pipeline runs it (the router's :class:`Route`)."""


@dataclass
class RunSummary:
    """What a run did, per device: samples, flagged samples by flag, bus errors, device
    errors (chip gone or misconfigured), and the driver's own counts (``driver``: resets
    detected, reconfigurations)."""

    simulated_s: float
    wall_s: float
    samples: dict[str, int]
    flagged: dict[str, dict[str, int]]
    bus_errors: dict[str, int]
    device_errors: dict[str, int]
    estimates: dict[str, int]
    warnings: list[str]
    driver: dict[str, dict[str, int]] = field(default_factory=dict)
    buses: dict[str, str] = field(default_factory=dict)
    """Buses that chose how to reach their devices when opened, by profile name: how (e.g.
    an SMBus-only I2C adapter read through SMBus transfers)."""
    frames: dict[str, dict[str, int]] = field(default_factory=dict)
    """Per accounted device (imuhal.pipeline.accounting): frames produced, delivered and
    ``lost_<cause>``."""
    sinks: dict[str, dict[str, int]] = field(default_factory=dict)
    """Counts of the sinks that keep some (``run_counts()``, e.g. the MQTT sink's sent,
    queued and dropped messages), by sink name."""
    learned: dict[str, dict[str, Any]] = field(default_factory=dict)
    """Per device learning in flight: :meth:`HardIronLearner.status` under the device's
    name, :meth:`AccelOffsetLearner.status` under ``<device> accel``."""
    triggers: dict[str, dict[str, int]] = field(default_factory=dict)
    """Per device read on a data-ready line (imuhal.pipeline.triggers.LineTrigger): edges,
    reads, overwritten and lost edges, watchdog fallbacks, polls while fallen back and
    returns to the line."""
    contained: dict[str, dict[str, int]] = field(default_factory=dict)
    """Per plugin instance that failed (``estimator 'ahrs'``, ``driver of 'imu'``, ``sink
    'csv'``): exceptions, rejected estimates, missed deadlines, ``disabled``
    (imuhal.pipeline.containment)."""

    def describe(self) -> str:
        lines = [f"ran {self.simulated_s:.1f} s in {self.wall_s:.2f} s wall time"]
        lines += [f"  bus {name}: {how}" for name, how in self.buses.items()]
        for dev, n in self.samples.items():
            bad = sum(self.flagged.get(dev, {}).values())
            extra = f", {bad} flagged {dict(self.flagged[dev])}" if bad else ""
            errs = self.bus_errors.get(dev, 0)
            faults = self.device_errors.get(dev, 0)
            own = ", ".join(f"{k.replace('_', ' ')} {v}"
                            for k, v in self.driver.get(dev, {}).items() if v)
            lines.append(f"  {dev}: {n} samples{extra}" + (f", {errs} bus errors" if errs else "")
                         + (f", {faults} device errors" if faults else "")
                         + (f", driver: {own}" if own else ""))
            if dev in self.frames:
                lines.append(f"    frames: {describe_frames(self.frames[dev])}")
            if dev in self.triggers:
                lines.append(f"    data-ready line: {describe_trigger(self.triggers[dev])}")
        for est, n in self.estimates.items():
            lines.append(f"  {est}: {n} estimates")
        for name, counts in self.sinks.items():
            lines.append(f"  {name}: " + ", ".join(f"{k.replace('_', ' ')} {v}"
                                                  for k, v in counts.items()))
        for dev, st in self.learned.items():
            lines.append(f"  {dev}: {_learned_words(st)}")
        for label, counts in self.contained.items():
            lines.append(f"  {label}: " + ", ".join(f"{k.replace('_', ' ')} {v}"
                                                   for k, v in counts.items()))
        lines += [f"  warning: {w}" for w in self.warnings]
        return "\n".join(lines)


def _learned_words(status: dict[str, Any]) -> str:
    """One line for the run summary: what was learned in flight and how sure it is."""
    if status.get("quantity") == "accel":
        return _accel_words(status)
    h, std = status.get("hard_iron_ut"), status.get("std_ut")
    if h is None or std is None:
        return f"hard iron: learning in flight ({status['readings']} readings, no fit yet)"
    fit = ", ".join(f"{v:.1f} +- " + ("?" if e is None else f"{e:.1f}")
                    for v, e in zip(h, std, strict=True))
    state = "learned in flight, applied" if status["converged"] else \
        "learning in flight, not applied yet"
    return f"hard iron {state}: ({fit}) uT from {status['readings']} readings"


def _accel_words(status: dict[str, Any]) -> str:
    """The accelerometer offset learned in flight (body frame), for the run summary."""
    b, std = status.get("offset_mg"), status.get("std_mg")
    if b is None or std is None:
        return "accelerometer offset: learning in flight (not started: needs an AHRS " \
            "estimate and a GNSS velocity or a pressure)"
    fit = ", ".join(f"{v:.1f} +- {e:.1f}" for v, e in zip(b, std, strict=True))
    axes = "xyz"
    learned = "".join(a for a, done in zip(axes, status["learned_axes"], strict=True) if done)
    state = "learned in flight, applied" if status["converged"] else \
        f"learning in flight, applied on {learned}" if learned else \
        "learning in flight, not applied yet"
    return (f"accelerometer offset {state}: ({fit}) mg (body frame) from "
            f"{status['updates']} measurements")


class _Readings(list[Sample]):
    """A poll's blocks when each holds one frame: their readings (one per stream)."""

    __slots__ = ()


def _recovered_clip(sample: Sample) -> bool:
    """A flagged reading an estimator still takes: a gyro reading clipped at the chip's full
    scale, an AHRS integrates it clipped rather than leave a gap (angular-rate recovery);
    nothing else flagged is ever fused."""
    flags = sample.flags
    return bool(flags & SampleFlag.SATURATED) and not flags & ~CLIPPED \
        and isinstance(sample, GyroSample)


class Pipeline:
    def __init__(
        self,
        profile: BoardProfile,
        registry: Registry,
        board: Board,
        *,
        calibrated: bool = True,
        trace: Callable[[Transfer], None] | None = None,
        recorder: BusRecorder | None = None,
    ) -> None:
        """Probe and configure every enabled device of ``profile`` on ``board``'s buses.

        Usually called through :meth:`open` (real buses) or
        :func:`imuhal.emulation.open_emulated`. ``calibrated=False`` yields raw sensor-frame
        samples (no calibration, no mount rotation, no estimators): what calibration
        procedures measure. ``trace`` receives every bus transaction (see imuhal.bus.spy);
        ``recorder`` also records every clock reading, for ``imuhal replay``
        (imuhal.bus.recording).
        """
        self.profile = profile
        self.calibrated = calibrated
        self.registry = registry
        self.board = board
        clock = board.clock
        taps = [tap for tap in (trace, recorder.on_transfer if recorder else None) if tap]
        # The spies stamp transactions with the plain clock: their own readings are not part
        # of the run, so a replay does not have to make them.
        spied = dict(board.buses) if not taps else {
            name: SpyBus(bus, _fan_out(taps), clock) for name, bus in board.buses.items()}
        self._before_poll: Callable[[int, str], int] = board.before_poll
        if recorder is not None:
            recorder.attach(board.buses)
            clock = recorder.wrap_clock(clock)
            self._before_poll = recorder.wrap_before_poll(board.before_poll)
        self.clock = clock
        self._lines: dict[str, TriggerLine] = dict(getattr(board, "lines", None) or {})
        # a replayed recording's drivers ask for its transfers: the plan it was made with
        poll_plan: int = getattr(board, "poll_plan", POLL_PLAN)
        self._waiter = _waiter_of(board, clock, self._lines, recorder)
        # Whatever a bus plugin raises reaches the drivers as a BusError (contained per device).
        self.buses: dict[str, Bus] = {name: ContainedBus(bus) for name, bus in spied.items()}
        self._bus_modes = {name: bus.describe() for name, bus in board.buses.items()
                           if bus.describe() != bus.name}
        self.warnings: list[str] = []
        self.containment = Containment(self.warnings.append)
        self._watchdog = Watchdog(driver_timing(board))
        self._heap: list[tuple[int, int, str]] | None = None
        self._startup: GyroStartupStage | None = None
        self._fusion: list[Sample | Block] = []
        self._teachers: list[AccelTeacher] = []
        """The in-flight learners fed from the fusion queue (imuhal.pipeline.learning)."""
        self.learned_by_default = learned_by_default(profile, registry) if calibrated else {}
        """device -> the channels it learns in flight because its profile neither stores a
        record nor says otherwise (imuhal.pipeline.learning); none for raw samples (what a
        calibration procedure measures)."""
        """Valid body-frame readings (one-frame blocks as their sample) and blocks some
        estimator takes, waiting for their fusion step."""
        self._blocks_queued = False
        """Some block of several frames is queued (else the queue holds samples only)."""
        self._span_ns = [0, 0]  # first and last poll time of the latest poll loop (ns)
        self.devices: dict[str, DeviceRuntime] = {}
        self.estimators: list[EstimatorRuntime] = []
        chip_to_body = chip_to_body_rotations(profile)
        for name in device_order(profile):
            cfg = profile.devices[name]
            driver_cls = registry.drivers.get(cfg.driver)
            driver = driver_cls(self._link(cfg.bus, cfg.address), cfg.settings, device=name,
                                clock=clock)
            driver.poll_plan = poll_plan
            dev = DeviceRuntime(name=name, driver=driver, chip_to_body=chip_to_body[name],
                                calibration=None, required=cfg.required)
            self.devices[name] = dev
            if not dev.required:
                # looked for as in the run (Driver.look_for): a probe that listens for
                # seconds (a GNSS receiver) goes on in the poll loop, not before the start
                dev.next_poll_ns = self._look_for(dev, clock.now_ns())
                continue
            bring_up(driver, clock)
            self._joined(dev)
        self._device_rank = {name: i for i, name in enumerate(self.devices)}
        self.vertical_check = _vertical_check(self.devices)
        """GNSS heights and velD held against the board's barometer (None: the board lacks
        one of the two; imuhal.pipeline.crosscheck)."""
        self._checked_channels: frozenset[Quantity] = frozenset() \
            if self.vertical_check is None else _CROSS_CHECKED
        for name, ecfg in profile.estimators.items():
            est_cls = registry.estimators.get(ecfg.estimator)
            estimator = est_cls(ecfg.settings, instance=name)
            faults = self.containment.record(
                f"estimator {name!r}", plugin_origin(registry.estimators.entries[ecfg.estimator]))
            self.estimators.append(EstimatorRuntime(
                name=name,
                estimator=estimator,
                inputs=frozenset(ecfg.inputs) if ecfg.inputs is not None else None,
                consumes=tuple(est_cls.consumes),
                guard=EstimatorGuard(estimator, faults, self.warnings.append),
            ))
        self.router = Router(self.estimators, self._device_rank)
        """The routing rule (imuhal.pipeline.router), shared with the offline chain."""
        for runtime in self.estimators:
            self._bind(runtime)

    # -- construction -------------------------------------------------------------------

    @classmethod
    def open(
        cls,
        profile: BoardProfile,
        registry: Registry,
        *,
        calibrated: bool = True,
        trace: Callable[[Transfer], None] | None = None,
        recorder: BusRecorder | None = None,
    ) -> Pipeline:
        """Open the profile's real buses and probe its devices (see ``__init__`` for
        ``calibrated`` and ``trace``). For an emulated board use
        :func:`imuhal.emulation.open_emulated`."""
        board = open_hardware_board(profile, registry)
        try:
            return cls(profile, registry, board, calibrated=calibrated, trace=trace,
                       recorder=recorder)
        except BaseException:
            for bus in board.buses.values():
                bus.close()
            for line in board.lines.values():
                line.close()
            raise

    def _link(self, bus_ref: str, address: int) -> Link:
        parent, child = split_bus_ref(bus_ref)
        if child is None:
            return self.buses[parent].link(address)
        provided = self.devices[parent].driver.child_buses()
        if child not in provided:
            raise PluginError(
                f"device {parent!r} ({self.devices[parent].driver.name}) provides no bus "
                f"{child!r}; it provides: {', '.join(provided) or 'none'}"
            )
        return provided[child].link(address)

    def _checked_calibration(
        self, device: str, bus_ref: str, cal: DeviceCalibration | None,
        identity: DeviceIdentity, version: int,
    ) -> DeviceCalibration | None:
        if cal is None:
            return None
        kept = {}
        for channel, record in cal.records().items():
            b = record.binding
            if b is not None:
                found = (identity.driver, bus_ref, identity.address, identity.identity, version)
                wanted = (b.driver, b.bus, b.address, b.identity, b.calibration_version)
                if found != wanted:
                    self.warnings.append(
                        f"{device}: stored {channel} calibration was measured on "
                        f"{b.driver} at {b.bus}/0x{b.address:02X} ({b.identity}, calibration "
                        f"version {b.calibration_version}) but this is {identity.driver} at "
                        f"{bus_ref}/0x{identity.address:02X} ({identity.identity}, version "
                        f"{version}); NOT applied - recalibrate with `imuhal calibrate`"
                    )
                    continue
            kept[channel] = record
        return DeviceCalibration.model_validate(kept)

    def calibration_binding(self, device: str) -> CalibrationBinding:
        """The probed identity of ``device``, as stored with a calibration measured on it."""
        dev = self.devices[device]
        ident = dev.driver.identity
        if ident is None:
            raise ImuhalError(f"device {device!r} was not probed")
        return CalibrationBinding(
            driver=ident.driver, bus=self.profile.devices[device].bus,
            address=ident.address, identity=ident.identity,
            calibration_version=type(dev.driver).calibration_version)

    # -- running ------------------------------------------------------------------------

    def _joined(self, dev: DeviceRuntime) -> None:
        """``dev`` answered as its chip and is configured: check its stored calibration
        against what was found and start polling it."""
        driver = dev.driver
        assert driver.identity is not None
        cfg = self.profile.devices[dev.name]
        dev.calibration = self._checked_calibration(dev.name, cfg.bus, cfg.calibration,
                                                    driver.identity,
                                                    type(driver).calibration_version)
        learn = learning_settings(self.profile, dev.name, Quantity.MAG,
                                  self.learned_by_default)
        if isinstance(learn, MagInFlightSettings) and Quantity.MAG in type(driver).channels \
                and (dev.calibration is None or dev.calibration.mag is None) \
                and dev.mag_learner is None:
            dev.mag_learner = HardIronLearner(learn)
        self._start_accel_learning(dev)
        dev.present = True
        stream = driver.accounted_stream()
        if stream is not None and dev.ledger is None:
            dev.ledger = FrameLedger(*stream)
        dev.reconfigurations_seen = driver.health.reconfigurations
        self._take_streams(dev)
        if cfg.interrupt is not None and isinstance(dev.trigger, TimerTrigger):
            dev.trigger = self._line_trigger(dev, cfg.interrupt)
            self._time_ledger(dev)

    @staticmethod
    def _time_ledger(dev: DeviceRuntime) -> None:
        """A device whose frames are stamped at its chip's instants (read from its FIFO on
        the chip's clock, or on its data-ready line's edges) counts its gaps in the period
        those stamps show (``FrameLedger.chip_timed``)."""
        if dev.ledger is not None:
            dev.ledger.chip_timed = dev.buffered or isinstance(dev.trigger, LineTrigger)

    def _line_trigger(self, dev: DeviceRuntime, interrupt: InterruptConfig) -> LineTrigger:
        """The data-ready trigger of ``dev``, whose profile names its INT line; its
        watchdog counts the periods of the stream the driver accounts for (else its fastest
        stream)."""
        line = self._lines.get(dev.name)
        if line is None:
            raise ProfileError(self.profile.name, [
                f"devices.{dev.name}.interrupt: this board provides no line for it (a board "
                "that is neither real hardware nor emulated); remove interrupt: to poll it"])
        accounted = dev.driver.accounted_stream()
        periods = [spec.period_ns for spec in dev.streams]
        period_ns = accounted[1] if accounted is not None else min(periods, default=0)
        if period_ns <= 0:
            raise ProfileError(self.profile.name, [
                f"devices.{dev.name}.interrupt: driver {dev.driver.name!r} states no output "
                "rate to time the line's watchdog by; remove interrupt: to poll it"])
        return LineTrigger(line.name, period_ns, interrupt.watchdog_periods,
                           interrupt.edges_per_read)

    @property
    def streams(self) -> dict[str, tuple[StreamSpec, ...]]:
        """Every present device's stream specs (imuhal.core.streams), by device: the
        chip's range, resolution and rate as read back at its last configuration."""
        return {name: dev.streams for name, dev in self.devices.items() if dev.present}

    def _take_streams(self, dev: DeviceRuntime) -> None:
        """Collect ``dev``'s stream specs after it joined or was reconfigured: its full
        scales (the OUT_OF_RANGE check) come from them, and estimators fed by it are bound
        again when they changed."""
        driver = dev.driver
        streams = driver.streams()
        dev.full_scale = {ch: driver.full_scale(ch) for ch in type(driver).channels}
        if streams == dev.streams:
            return
        dev.streams = streams
        dev.deadline_s = driver_deadline_s(streams)
        dev.spec_of = {spec.quantity: spec for spec in reversed(streams)}
        dev.buffered = any(spec.time_source in BUFFERED_SOURCES for spec in streams)
        self._time_ledger(dev)
        for runtime in self.estimators:
            if runtime.inputs is None or dev.name in runtime.inputs:
                self._bind(runtime)

    def _bind(self, runtime: EstimatorRuntime) -> None:
        """Hand ``runtime``'s estimator the specs of its input devices' streams."""
        specs = [spec for name, dev in self.devices.items()
                 if dev.present and (runtime.inputs is None or name in runtime.inputs)
                 for spec in dev.streams]
        try:
            runtime.estimator.bind(specs)
        except StreamContradiction as exc:
            raise ProfileError(self.profile.name, [
                f"estimators.{runtime.name}.settings.{exc.key}: {exc.problem}"]) from None

    def events(self, duration_s: float | None = None) -> Iterator[Event]:
        """Samples (body frame, flagged ones included) and estimates, in time order.

        Repeated calls continue the run where the previous one stopped: devices are started
        once, so no chip is restarted mid-conversion. Breaking out of the iteration early is
        safe; the next call carries on from the next poll.

        At the start of the run, devices whose calibration asks for ``gyro_at_startup`` first
        have their gyro offsets measured while the board is still (imuhal.pipeline.startup);
        that phase is part of ``duration_s``, yields nothing, and carries on into the next
        call when a call ends before it does.
        """
        source = cast("Iterator[Event]", self._poll_events(duration_s, reads=False))
        try:
            stage = self._pending_startup()
            if stage is not None:
                # The phase carries over to the next call when this one ends before it does.
                self._run_startup(stage, source)
            yield from source
        finally:
            # the watchdog's CPU-time timers tick through a run only (containment.Watchdog)
            self._watchdog.pause()

    def blocks(self, duration_s: float | None = None
               ) -> Iterator[Event | Block | AttitudeBlock]:
        """``events`` with each read of several frames of a stream (a FIFO read) handed
        out as blocks (imuhal.core.blocks; body frame, flags final: the frames ``events``
        gives one by one), one per stream of the read, instead of a ``Sample`` per frame,
        and the attitude estimates an AHRS's block step made of such a read as one
        :class:`~imuhal.estimation.outputs.AttitudeBlock` instead of an estimate per
        frame; a register poll's readings, other estimates and everything else come as
        from ``events``. The blocks of one read come together, each in time order;
        ``Block.samples()`` gives a block's frames as the samples ``events`` would,
        ``AttitudeBlock.rows()`` its estimates as ``events`` would. For a consumer that
        takes frames on arrays (or only counts them): no per-frame object is built for
        it. The estimators get the same inputs as under ``events``, so the same
        estimates."""
        items = self._poll_events(duration_s, reads=True)
        try:
            stage = self._pending_startup()
            if stage is not None:
                source = _Expanded(self, items)
                self._run_startup(stage, source)
                # a read part-way handed out when the phase ended: the rest as its frames
                yield from source.rest_of_read()
            for item in items:
                if type(item) is _Read:
                    yield from item.blocks
                else:
                    yield cast("Event", item)
        finally:
            self._watchdog.pause()  # as in events

    def _pending_startup(self) -> GyroStartupStage | None:
        """The start-up phase (imuhal.pipeline.startup) when it is still to run."""
        if not self.calibrated:
            return None
        stage = self._startup = self._startup or self._startup_stage()
        return None if stage.done else stage


    def _startup_stage(self) -> GyroStartupStage:
        settings = startup_settings(
            {name: cfg.calibration for name, cfg in self.profile.devices.items()},
            {name: type(dev.driver).channels for name, dev in self.devices.items()})
        return GyroStartupStage(settings)

    def _run_startup(self, stage: GyroStartupStage, source: Iterator[Event]) -> None:
        """Feed ``stage`` raw samples from ``source`` (yielding nothing) until it is done or
        ``source`` ends, installing what it returns."""
        calibrated, self.calibrated = self.calibrated, False  # the procedures measure raw data
        moved = False
        try:
            for event in source:
                found = stage.feed(event) if isinstance(event, Sample) else None
                if found is not None:
                    self._install_startup(found)
                    moved = moved or found.moved
                if stage.done:
                    if moved:
                        # a measurement gave up as the board moved at switch-on, so the
                        # estimators' first readings may be a flying board's (an AHRS
                        # checks the attitude it aligns on them)
                        for runtime in self.estimators:
                            runtime.estimator.moving_at_start(event.t_ns)
                    return
        finally:
            self.calibrated = calibrated

    def _install_startup(self, found: StartupMeasurement) -> None:
        if found.warning is not None:
            self.warnings.append(found.warning)
            return
        dev = self.devices[found.device]
        dev.calibration = found.calibration(dev.calibration,
                                            self.calibration_binding(found.device))

    def framed_events(self, duration_s: float | None = None, *,
                      frame: str | None = None) -> Iterator[FramedEvent]:
        """``events`` expressed in ``frame`` (default: the profile's ``output_frame``): body
        samples and attitudes become FramedSample / FramedAttitude views in that convention;
        pressure, temperature and vertical estimates (up positive) come through unchanged."""
        target = get_convention(frame if frame is not None else self.profile.output_frame)
        for event in self.events(duration_s):
            yield express(event, target)

    def _schedule(self) -> list[tuple[int, int, str]]:
        """The poll heap, built at the first ``events`` call: (due time, rank, device)."""
        if self._heap is None:
            now = self.clock.now_ns()
            self._heap = []
            for name, dev in self.devices.items():
                if dev.present:
                    dev.next_poll_ns = dev.driver.start(now)
                else:  # an optional device still looked for: its next step
                    dev.next_poll_ns = max(now, dev.next_poll_ns)
                if dev.present and isinstance(dev.trigger, LineTrigger):
                    dev.next_poll_ns = dev.trigger.started(now)
                heapq.heappush(self._heap, (dev.next_poll_ns, self._device_rank[name], name))
        return self._heap

    def _poll_events(self, duration_s: float | None, *, reads: bool
                     ) -> Iterator[Event | AttitudeBlock | _Read]:
        """The poll loop: every event in time order; ``reads``: each read of several frames
        as one :class:`_Read` (``blocks``), else its frames one by one (``events``)."""
        heap = self._schedule()
        start = self.clock.now_ns()
        end = None if duration_s is None else start + round(duration_s * 1e9)
        self._span_ns = [start, start]
        lines = bool(self._lines)
        while heap:
            t_ns, rank, name = heap[0]
            if lines:
                woke = self._waiter.wait(t_ns if end is None else min(t_ns, end))
                if woke:
                    yield from self._on_edges(woke, reads)
                    continue
            if end is not None and t_ns >= end:
                self._span_ns[1] = end
                break
            heapq.heappop(heap)
            if lines and self._superseded(name, t_ns):
                continue
            self.clock.sleep_until(t_ns)
            # Estimator inputs wait until every sample of their instant is in (fusion order).
            if self._fusion:
                fused = self._fuse(t_ns, reads)
                if fused:
                    yield from fused
            due_ns = t_ns
            t_ns = self._before_poll(t_ns, name)
            dev = self.devices[name]
            if self._put_off(dev, due_ns, t_ns):
                continue
            frames, next_ns = self._contained_service(dev, t_ns)
            if dev.ledger is not None:
                self._account(dev)
            dev.next_poll_ns = max(self._next_due(dev, t_ns, next_ns), t_ns + 1)
            heapq.heappush(heap, (dev.next_poll_ns, rank, name))
            if frames:  # _hand_out's register-poll case written out: one call a reading
                if type(frames) is _Readings:
                    for sample in frames:
                        yield self._process_one(dev, sample)
                else:
                    yield from self._hand_out(dev, frames, reads)
            if dev.ledger is not None:
                self._account_slides(dev)
        if end is not None:
            self.clock.sleep_until(end)
            yield from self._drain(end, reads)
        if self._fusion:
            yield from self._fuse(None, reads)

    def _drain(self, t_ns: int, reads: bool) -> Iterator[Sample | _Read]:
        """The run ends at ``t_ns``: what each driver read and still holds
        (``Driver.drain``: FIFO frames waiting for their time stamps) is handed out, so
        nothing read is lost uncounted."""
        for dev in self.devices.values():
            if not dev.present or dev.isolated or dev.needs_recovery:
                continue
            try:
                held = dev.driver.drain(t_ns)
            except Exception as exc:  # a driver plugin's bug is its device's alone
                self._driver_failed(dev, t_ns, exc)
                continue
            if held:
                yield from self._hand_out(dev, _frames(held), reads)

    def _read_frames(self, read: _Read) -> Iterator[Sample]:
        """A read's frames handed out one by one in time order
        (imuhal.core.blocks.interleaved). When the start-up phase switches calibration on
        while they are handed out, the frames not handed out yet are calibrated and queued
        then, as single readings would have been."""
        frames = interleaved(read.blocks)
        for i, frame in enumerate(frames):
            yield frame
            if self.calibrated and not read.calibrated:
                rest = [self._to_body(read.dev, b) for b in blocks_of(frames[i + 1:])]
                yield from interleaved(rest)
                return

    def _hand_out(self, dev: DeviceRuntime, frames: _Readings | list[Block],
                  reads: bool) -> Iterator[Sample | _Read]:
        """A poll's readings or blocks through the steps, in the order they are handed out:
        readings one by one, the blocks of several frames (a FIFO read) at once, as one
        :class:`_Read` (``reads``: its frames become samples only where a consumer asks)
        or as its frames one by one."""
        if isinstance(frames, _Readings):
            # one frame per block (a register poll): each reading through the steps as it
            # is handed out (the start-up phase may switch calibration on between two)
            for sample in frames:
                yield self._process_one(dev, sample)
        elif frames:
            calibrated = self.calibrated
            read = _Read(dev, [self._process(dev, b) for b in frames], calibrated)
            if reads:
                yield read
            else:
                yield from self._read_frames(read)

    @staticmethod
    def _aim(ledger: FrameLedger, due_ns: int, t_ns: int) -> tuple[int, int]:
        """Where a put-off poll of a driver searching its chip's instants
        (``Driver.polls_after_instants``) aims, and how much after the phase it is counted
        on. Such a driver polls a guard apart until new data appear, so a poll due can lie
        anywhere from just before its chip's instant to a period after it: aimed from
        there, the put-off poll's stamp can lie up to a period after the instant where the
        frame before it lay within a guard, and the gap rounds to a frame too many. It
        aims a guard after the phase the latest frame was counted on, whole periods on,
        and is counted on that phase (so put-offs in a row do not move it), while a chip
        clock 2 % off cannot have moved its instants by a guard since
        (AIM_FROM_FRAME_PERIODS); else a guard after the due time, counted at its
        stamp."""
        guard_ns = ledger.period_ns // 8
        counted_ns = ledger.counted_ns
        if counted_ns is not None and \
                t_ns - counted_ns <= AIM_FROM_FRAME_PERIODS * ledger.period_ns:
            return counted_ns + guard_ns, guard_ns
        return due_ns + guard_ns, 0

    def _put_off(self, dev: DeviceRuntime, due_ns: int, t_ns: int) -> bool:
        """A poll due at ``due_ns`` comes at ``t_ns``: the run's span moves on, and a late
        poll is put off to its device's grid (True: ``_on_phase``) or charged to the
        ledger (``_note_late``)."""
        span = self._span_ns
        if t_ns > span[1]:
            span[1] = t_ns
        if span[1] == due_ns:
            # on time, and no poll before it came later (the usual poll): nothing to put
            # off and nothing late (what _on_phase and _note_late find, without them); a
            # put-off poll on time is counted on the phase it aimed a guard after (_aim)
            if dev.put_off and dev.aim_offset_ns and dev.ledger is not None:
                dev.ledger.count_at(t_ns, due_ns - dev.aim_offset_ns)
            dev.put_off = 0
            return False
        if self._on_phase(dev, due_ns, t_ns):
            return True
        if dev.resumed:
            self._count_late_retry(dev, due_ns, t_ns)
        self._note_late(dev, due_ns, t_ns)
        return False

    def _on_phase(self, dev: DeviceRuntime, due_ns: int, t_ns: int) -> bool:
        """A poll due at ``due_ns`` that can only happen at ``t_ns``, half a frame period or
        more later (the pipeline's one thread was held: a host stall, another device's
        slow poll or recovery): True when it is put off to the next point of the device's
        own grid, ``due_ns`` plus whole frame periods (the loss is charged to
        ``host_stall``). Its chip keeps measuring on its own clock at the phase the due
        time had, so a reading taken on that phase carries the measurement an on-time poll
        there would, stamped with the same lag after it: a stamp neither back at the old
        due time nor up to a period after its data, and the frame ledger's gap, counted
        from stamp to stamp, is exact. At most one more frame goes than a poll at once
        would have read, counted.

        Not put off (False; the poll happens at ``t_ns``): a chip the driver paces (its
        conversion then measures the world of ``t_ns``), one whose frames the chip buffers
        or a data-ready line times, a device without an accounted period, one recovering,
        a poll put off PUT_OFF_AT_MOST times in a row already (a host whose every wake-up
        comes late, a coarse timer, would otherwise never poll it; fewer times, a stall
        that follows another: the frame it reads is counted from the grid point before it,
        ``FrameLedger.count_at``), and a poll late by less than half a period (it reads the
        frame it was due for while its grid lies less than half a period after the chip's
        instants, and the ledger counts that frame at the due time: from the stamp, lags
        that differ by half a period or more between the two ends of a gap, a poll grid
        a guard after the instants and one 2.6 ms late of 5, round to a frame too few)."""
        ledger = dev.ledger
        if ledger is None or dev.buffered or dev.needs_recovery or dev.resumed \
                or not dev.present or not isinstance(dev.trigger, TimerTrigger) \
                or dev.driver.host_paced:
            dev.put_off = 0
            return False
        period_ns = ledger.period_ns
        # a put-off poll aimed a guard after the phase of a frame is counted on that phase
        offset = dev.aim_offset_ns if dev.put_off else 0
        if 2 * (t_ns - due_ns) < period_ns:
            dev.put_off = 0
            if t_ns > due_ns - offset:  # it reads the frame it was due for: counted there
                ledger.count_at(t_ns, due_ns - offset)
            return False
        aim_ns = due_ns
        if not dev.put_off:
            dev.aim_offset_ns = offset = 0
            if dev.driver.polls_after_instants:
                aim_ns, offset = self._aim(ledger, due_ns, t_ns)
                dev.aim_offset_ns = offset
        if dev.put_off >= PUT_OFF_AT_MOST:
            dev.put_off = 0
            grid_ns = aim_ns + (t_ns - aim_ns) // period_ns * period_ns
            # counted from the phase the frame before was counted on, not from the aim a
            # guard after it: a poll up to a guard past a point of that phase comes after
            # the chip's instant there (a guard before it at most), so it reads that frame
            # (from the aim's grid, the frame before: the gy91 AK8963 counted a field too
            # few after a 130 ms chain of host stalls)
            phase_ns = grid_ns - offset + (t_ns - grid_ns + offset) // period_ns * period_ns
            if t_ns > phase_ns and dev.driver.polls_after_instants:
                # a grid near its chip's instants: counted at the point however little
                # later it comes (from its stamp, a lag under half a period can still
                # differ from the frames' before by more: the grid was aimed a guard later
                # than they were stamped)
                ledger.count_at(t_ns, phase_ns)
            elif 2 * (t_ns - grid_ns) >= period_ns:
                # a grid at an unknown lag after them: from its stamp it could round either
                # way
                ledger.count_at(t_ns, grid_ns - offset)
            return False
        at_ns = aim_ns + -(-(t_ns - aim_ns) // period_ns) * period_ns
        if at_ns == t_ns:  # late by whole periods: on the grid already
            dev.put_off = 0
            if offset:
                ledger.count_at(t_ns, t_ns - offset)
            return False
        ledger.note("host_stall", at_ns=due_ns)
        dev.put_off += 1
        dev.next_poll_ns = at_ns
        heapq.heappush(self._schedule(), (at_ns, self._device_rank[dev.name], dev.name))
        return True

    @staticmethod
    def _count_late_retry(dev: DeviceRuntime, due_ns: int, t_ns: int) -> None:
        """A retry after a bus error (``Driver.resume``) of a driver whose grid searches its
        chip's instants, made at ``t_ns`` more than a guard after ``due_ns`` (the host's one
        thread held: past ``FrameLedger.retried``'s window): it is read at once, never put
        off (it fetches the frame the failed read missed), and counted at the latest point
        of the phase its latest frame was counted on at or before its stamp, as a poll read
        off its phase after PUT_OFF_AT_MOST put-offs: the chip's instant there lies at most
        a guard before that point, its next one about a period later. From its stamp, a
        retry 2.8 ms late of a poll itself 1.5 ms late (of 5) read the frame due there 4.5
        ms after its instant, where the frame before lay 0 to 0.4 ms after its own, and the
        gap rounded to a frame the chip never made (the seed rc board's MAX21105 at 10 % bus
        errors, seed 3: 2001 for the chip's 2000; from poll plan LATE_RETRY_PLAN). Only a
        point after that frame's (a retry within a period of it that brings a new frame read
        the next one) and while the frame is recent (AIM_FROM_FRAME_PERIODS); a retry whose
        read found a frame overwritten came after the next instant after all (within that
        guard) and is counted at its stamp (``count_at(unless_skipped=True)``)."""
        ledger = dev.ledger
        if ledger is None or dev.buffered or not dev.driver.polls_after_instants \
                or dev.driver.poll_plan < LATE_RETRY_PLAN:
            return
        counted_ns = ledger.counted_ns
        period_ns = ledger.period_ns
        if counted_ns is None or t_ns - due_ns <= period_ns // 8 \
                or t_ns - counted_ns > AIM_FROM_FRAME_PERIODS * period_ns:
            return
        phase_ns = counted_ns + (t_ns - counted_ns) // period_ns * period_ns
        if counted_ns < phase_ns < t_ns:
            ledger.count_at(t_ns, phase_ns, unless_skipped=True)

    def _note_late(self, dev: DeviceRuntime, due_ns: int, t_ns: int) -> None:
        """A read at ``t_ns`` that was due at ``due_ns``: more than half a frame period late
        (this device's stall, or another's slow poll) it may have cost frames, a cause the
        ledger charges them to; not for a chip that buffers its frames (a FIFO read on its
        own clock), where a late read loses nothing until the FIFO overflows, a cause of
        its own."""
        ledger = dev.ledger
        if ledger is not None and not dev.buffered and \
                max(t_ns, self._span_ns[1]) - due_ns > ledger.period_ns // 2:
            ledger.note("host_stall", at_ns=due_ns)

    def _superseded(self, name: str, t_ns: int) -> bool:
        """A popped deadline that a read on an edge replaced (the heap keeps the old entry);
        a deadline that is the watchdog firing makes the line's device polled, said once."""
        dev = self.devices[name]
        if t_ns != dev.next_poll_ns:
            return True
        trigger = dev.trigger
        if isinstance(trigger, LineTrigger) and dev.present and not dev.needs_recovery \
                and trigger.expired(t_ns):
            self._warn_once(dev, "line silent", f"{name}: {trigger.describe_silence()}")
        return False

    def _next_due(self, dev: DeviceRuntime, t_ns: int, driver_next_ns: int) -> int:
        """When ``dev`` is read next after a read at ``t_ns``: as its trigger says, unless
        it is recovering (then as the recovery says)."""
        if not dev.present or dev.needs_recovery or dev.resumed:
            return driver_next_ns
        return dev.trigger.due(t_ns, driver_next_ns)

    def _on_edges(self, woke: dict[str, list[TriggerEdge]], reads: bool
                  ) -> Iterator[Event | AttitudeBlock | _Read]:
        """Read each device whose line raised edges, once, stamped with its newest edge
        (a host that came late finds the chip's newest sample: the edges before it are
        counted overwritten)."""
        for name in sorted(woke, key=self._device_rank.__getitem__):
            dev = self.devices[name]
            edges = woke[name]
            trigger = dev.trigger
            if not isinstance(trigger, LineTrigger) or not dev.present or dev.needs_recovery:
                continue  # a recovering device is retried on its own schedule
            due_ns = edges[0].t_ns
            if self._fusion:
                fused = self._fuse(due_ns, reads)
                if fused:
                    yield from fused
            t_ns = self._before_poll(due_ns, name)
            edges += self._waiter.take(name)  # those that came while the host was late
            edge = trigger.took(edges)
            dev.edges_ns += trigger.taken_ns  # to the driver with its next poll
            if edge is None:  # fewer edges than make a read: wait for more
                dev.next_poll_ns = trigger.watchdog_at_ns
                heapq.heappush(self._schedule(), (dev.next_poll_ns, self._device_rank[name],
                                                  name))
                continue
            self._note_late(dev, due_ns, t_ns)
            self._span_ns[1] = max(t_ns, self._span_ns[1])
            samples, next_ns = self._contained_service(dev, edge.t_ns)
            if dev.ledger is not None:
                self._account(dev)
            dev.next_poll_ns = max(self._next_due(dev, edge.t_ns, next_ns), t_ns + 1)
            heapq.heappush(self._schedule(), (dev.next_poll_ns, self._device_rank[name], name))
            yield from self._hand_out(dev, samples, reads)
            if dev.ledger is not None:
                self._account_slides(dev)

    def _contained_service(self, dev: DeviceRuntime, t_ns: int
                           ) -> tuple[_Readings | list[Block], int]:
        """``_service`` within the driver's deadline, with whatever the driver plugin raises
        beyond the ImuhalErrors ``_service`` handles contained to its device
        (imuhal.pipeline.containment)."""
        if dev.isolated:
            return [], NEVER_NS
        watchdog = self._watchdog
        armed = False
        try:
            # arm and disarm inside the try that catches the deadline: the alarm can fire
            # between arming and the call or after the call returns, before disarm (seen at
            # load 35), and must still isolate the device rather than escape the run
            try:
                armed = watchdog.arm(dev.deadline_s)
                return self._service(dev, t_ns)
            finally:
                if armed:
                    watchdog.disarm()
        except DriverDeadline:
            self._isolate(dev, t_ns, "did not return from a call within its deadline of "
                          + watchdog.timing.describe(dev.deadline_s))
            return [], NEVER_NS
        except RunEnded:
            raise  # a replayed recording ran out or diverged: the whole run ends
        except Exception as exc:  # a driver plugin's bug is its device's alone
            return [], self._driver_failed(dev, t_ns, exc)

    def _driver_failures(self, dev: DeviceRuntime) -> PluginFaults:
        """The containment record of ``dev``'s driver."""
        registration = self.registry.drivers.entries.get(dev.driver.name)
        origin = plugin_origin(registration) if registration is not None else dev.driver.name
        return self.containment.record(f"driver of {dev.name!r}", origin)

    def _isolate(self, dev: DeviceRuntime, t_ns: int, why: str) -> None:
        faults = self._driver_failures(dev)
        faults.counts["deadlines_missed"] += 1
        dev.isolated = True
        dev.device_errors += 1
        faults.disable(f"at t={t_ns / 1e9:.3f} s: it {why}; device {dev.name!r} is isolated",
                       self.containment.warn)

    def _driver_failed(self, dev: DeviceRuntime, t_ns: int, exc: Exception) -> int:
        """A driver raised something else than an ImuhalError: a device error (counted,
        recovered with the usual backoff); a driver that keeps failing isolates its device."""
        dev.device_errors += 1
        dev.resumed = 0
        disabled = self._driver_failures(dev).failed(
            t_ns, "exceptions", f"raised {describe_exception(exc)} at t={t_ns / 1e9:.3f} s; "
            f"device {dev.name!r} is recovered", self.containment.warn)
        if disabled:
            dev.isolated = True
            return NEVER_NS
        dev.needs_recovery = True
        dev.failures += 1
        return t_ns + min(RECOVERY_BACKOFF_NS, RETRY_FIRST_NS << min(dev.failures - 1, 16))

    def _service(self, dev: DeviceRuntime, t_ns: int) -> tuple[_Readings | list[Block], int]:
        """Whatever ``dev`` needs at ``t_ns``: a poll, a recovery, or a look for an optional
        device not yet found. Returns its blocks (blocks of one frame each as their
        readings, :class:`_Readings`) and when it is next due."""
        if not dev.present:
            return [], self._look_for(dev, t_ns)
        if dev.needs_recovery:
            return [], self._recover(dev, t_ns)
        try:
            # dev's poll as blocks (Driver.poll_blocks). For a driver that leaves
            # poll_blocks to the base class its adapter is written out here: a poll whose
            # readings are of different streams (a register poll) is a block of one frame
            # per reading, kept as the readings; one with several readings of a stream (a
            # FIFO read) is grouped into blocks (imuhal.core.blocks.blocks_of)
            driver = dev.driver
            if dev.edges_ns:
                driver.data_ready(dev.edges_ns)
                dev.edges_ns = []
            if dev.own_blocks and driver.builds_blocks:
                polled = driver.poll_blocks(t_ns)
                blocks = polled.blocks
                next_ns = polled.next_poll_ns
                frames: _Readings | list[Block] = \
                    _Readings(b.samples()[0] for b in blocks) \
                    if all(len(b) == 1 for b in blocks) else blocks
            else:
                result = driver.poll(t_ns)
                frames, next_ns = _frames(result.samples), result.next_poll_ns
        except BusError:
            dev.bus_errors += 1
            if dev.ledger is not None:
                dev.ledger.note("bus_error")
            return [], self._after_bus_error(dev, t_ns)
        except ImuhalError as exc:
            # A driver that found its chip gone or misconfigured mid-run: the device is
            # recovered like after a bus error; the run goes on for the others.
            dev.device_errors += 1
            self._warn_once(dev, type(exc).__name__, f"{dev.name}: {exc}")
            dev.resumed = 0
            return [], self._recover(dev, t_ns)
        dev.resumed = 0
        return frames, next_ns

    def _after_bus_error(self, dev: DeviceRuntime, t_ns: int) -> int:
        """Recovery in proportion: a transfer that fails after a good poll is most likely a
        glitch, so the driver first resumes (``Driver.resume``: retry the transfer, or check
        the chip kept its state) without resetting the chip and losing its measurement in
        flight; a failure after the driver's ``resumes_in_a_row`` resumes before a poll
        completes (one for most), a chip that lost its state, or a driver that cannot tell
        gets the full recovery (re-probe and reconfigure)."""
        if dev.resumed < dev.driver.resumes_in_a_row:
            try:
                next_ns = dev.driver.resume(t_ns)
            except ImuhalError as exc:
                if isinstance(exc, BusError):
                    dev.bus_errors += 1
                next_ns = None
            if next_ns is not None:
                dev.resumed += 1
                if dev.ledger is not None:
                    dev.ledger.retried(t_ns)
                return next_ns
        dev.resumed = 0
        return self._recover(dev, t_ns)

    def _account(self, dev: DeviceRuntime) -> None:
        """A reconfiguration of the chip since the ledger last looked costs frames ("reset");
        the frame period follows the configuration."""
        assert dev.ledger is not None
        driver = dev.driver
        if driver.health.fifo_overflows != dev.fifo_overflows_seen:
            dev.fifo_overflows_seen = driver.health.fifo_overflows
            dev.ledger.note("fifo_overflow")
        health = driver.health
        if health.idle is not None and health.idle != dev.idle_seen:
            dev.idle_seen = health.idle
            dev.ledger.idle(*health.idle)
        if health.adjacent is not None and health.adjacent != dev.adjacent_seen:
            dev.adjacent_seen = health.adjacent
            dev.ledger.adjacent(*health.adjacent)
        if health.overrun_ns != dev.overrun_seen_ns:
            dev.overrun_seen_ns = health.overrun_ns
            dev.ledger.overrun(health.overrun_ns)
        if health.skipped_ns != dev.skipped_seen_ns:
            dev.skipped_seen_ns = health.skipped_ns
            dev.ledger.skipped(health.skipped_ns)
        if driver.health.reconfigurations != dev.reconfigurations_seen:
            dev.reconfigurations_seen = driver.health.reconfigurations
            dev.ledger.note("reset")
            stream = driver.accounted_stream()
            if stream is not None:
                dev.ledger.channel, dev.ledger.period_ns = stream

    @staticmethod
    def _account_slides(dev: DeviceRuntime) -> None:
        """The time a host-paced chip's schedule slid in a read, once its frames are counted:
        a driver slides its cadence after the frame it hands out (the next conversion is
        late), so the slide belongs to the gap after that frame."""
        assert dev.ledger is not None
        slid_ns = dev.driver.health.not_converted_ns - dev.not_converted_seen_ns
        if slid_ns:
            dev.not_converted_seen_ns = dev.driver.health.not_converted_ns
            dev.ledger.slid(slid_ns)

    def _look_for(self, dev: DeviceRuntime, t_ns: int) -> int:
        """A step of looking for an optional device not found yet (``Driver.look_for``: a
        probe that listens for seconds goes in steps between the other devices' polls, so
        they lose nothing to it); the time of its next step, its next look, or its first
        poll once found. The first look is made at the pipeline's start."""
        try:
            next_ns = dev.driver.look_for(t_ns)
        except ImuhalError as exc:
            if isinstance(exc, BusError):
                dev.bus_errors += 1
            self._warn_once(dev, "absent", f"{dev.name}: not found at start-up, running "
                            f"without it and looking for it every {JOIN_RETRY_NS / 1e9:g} s "
                            f"({exc})")
            return t_ns + JOIN_RETRY_NS
        if next_ns is not None:
            return next_ns
        self._joined(dev)
        if "absent" in dev.warned:
            self.warnings.append(f"{dev.name}: found at t={t_ns / 1e9:.3f} s; it joins the "
                                 "run")
        if self._heap is None:  # found by the first look: _schedule starts it with the others
            return 0
        next_ns = dev.driver.start(max(t_ns, self.clock.now_ns()))
        if isinstance(dev.trigger, LineTrigger):  # its first edge is awaited from now
            return dev.trigger.started(max(t_ns, self.clock.now_ns()))
        return next_ns

    def _recover(self, dev: DeviceRuntime, t_ns: int) -> int:
        """Bring a device back after a failed poll. A failed attempt is retried after a
        backoff that doubles from RETRY_FIRST_NS up to RECOVERY_BACKOFF_NS; a glitch costs
        a few milliseconds, a chip that stays away is retried every 100 ms and reported."""
        try:
            next_ns = dev.driver.recover(t_ns)
        except ImuhalError as exc:
            # every failed attempt is counted: a chip that answers with the wrong identity
            # or will not take its configuration (DeviceNotFoundError, ConfigurationError)
            # is a device error, as the same exception from a poll is
            if isinstance(exc, BusError):
                dev.bus_errors += 1
            else:
                dev.device_errors += 1
            if not dev.failures:
                dev.failing_since_ns = t_ns
            dev.failures += 1
            dev.needs_recovery = True
            backoff = min(RECOVERY_BACKOFF_NS, RETRY_FIRST_NS << min(dev.failures - 1, 16))
            if dev.failures >= REPORT_AFTER_FAILURES:
                # once per kind of error (and what a probe found), so a later, different
                # cause is reported too
                kind = f"recovery {type(exc).__name__} {getattr(exc, 'found', '')}"
                self._warn_once(dev, kind,
                                f"{dev.name}: recovery failed {dev.failures} times in a row "
                                f"from t={dev.failing_since_ns / 1e9:.3f} s (retrying every "
                                f"{RECOVERY_BACKOFF_NS / 1e9:g} s at most): {exc}")
            return t_ns + backoff
        dev.failures = 0
        dev.needs_recovery = False
        self._take_streams(dev)
        return next_ns

    def _start_accel_learning(self, dev: DeviceRuntime) -> None:
        """An accelerometer learner for ``dev`` when its profile asks (``accel_in_flight``)
        or by default (imuhal.pipeline.learning) and it has no stored accelerometer record;
        started from the attitude of the estimators ``dev`` feeds."""
        learn = learning_settings(self.profile, dev.name, Quantity.ACCEL,
                                  self.learned_by_default)
        driver = type(dev.driver)
        if not isinstance(learn, AccelInFlightSettings) or Quantity.ACCEL not in driver.channels \
                or (dev.calibration is not None and dev.calibration.accel is not None) \
                or dev.accel_teacher is not None:
            return
        prior = driver.specified_offset.get(Quantity.ACCEL)
        learner = AccelOffsetLearner(learn) if prior is None else \
            AccelOffsetLearner(learn, prior_offset_m_s2=prior)
        feeders = frozenset(n for n, e in self.profile.estimators.items()
                            if e.inputs is None or dev.name in e.inputs)

        def apply() -> None:
            learner.mark_applied()
            cal = dev.calibration or DeviceCalibration()
            dev.calibration = cal.model_copy(update={"accel": learner.record(
                dev.chip_to_body_rows, binding=self.calibration_binding(dev.name),
                date=now())})

        dev.accel_teacher = AccelTeacher(dev.name, learner, feeders, apply)
        self._teachers.append(dev.accel_teacher)

    def _warn_once(self, dev: DeviceRuntime, key: str, message: str) -> None:
        """Record a device's warning of one kind once, not at every retry."""
        if key not in dev.warned:
            dev.warned.add(key)
            self.warnings.append(message)

    def _process_one(self, dev: DeviceRuntime, raw: Sample) -> Sample:
        """:meth:`_process` for a block of one frame, on its sample: the same steps and
        floats (imuhal.pipeline.processing takes a one-frame block on its sample too),
        without building a block around each reading of a register poll."""
        channel = raw.channel
        flags = validity_flags(raw, dev.full_scale.get(channel), dev.last_valid_ns.get(channel))
        sample = raw if flags == raw.flags else raw.flagged(flags)
        if channel in self._checked_channels:
            assert self.vertical_check is not None
            sample = self.vertical_check.observe(sample)
        dev.samples += 1
        if sample.flags:
            self._count_flags(dev, sample)
        else:
            dev.last_valid_ns[channel] = sample.t_ns
        if dev.ledger is not None:
            loss = dev.ledger.observe(sample)
            if loss is not None:
                self._gap(dev, sample.t_ns, loss)
        if not self.calibrated:
            return sample
        if dev.mag_learner is not None and isinstance(sample, MagSample):
            self._learn(dev, [sample])
        # Flagged samples are only rotated, not calibrated.
        sample = calibrate_to_body(sample, dev.calibration if sample.valid else None,
                                   dev.chip_to_body_rows)
        if self.estimators and (not sample.flags or _recovered_clip(sample)) \
                and self.router.takes(sample.device, type(sample)):
            self._fusion.append(sample)
        return sample

    def _process(self, dev: DeviceRuntime, raw: Block) -> Block:
        """One block of ``dev`` through validity, calibration and rotation, once for all its
        frames (imuhal.pipeline.processing); its fusable frames are queued for the
        estimators (fused in order by ``_fuse``)."""
        channel = raw.quantity
        if raw.spec is None:
            raw.spec = dev.spec_of.get(channel)
        block, last = validity_block(raw, dev.full_scale.get(channel),
                                     dev.last_valid_ns.get(channel))
        if last is not None:
            dev.last_valid_ns[channel] = last
        if channel in self._checked_channels:
            assert self.vertical_check is not None
            check = self.vertical_check.observe
            block = Block.from_samples([check(s) for s in block.samples()], block.spec)
        dev.samples += len(block)
        if block.flagged:
            for sample in block.samples():
                if sample.flags:
                    self._count_flags(dev, sample)
        if dev.ledger is not None:
            for t_ns, loss in dev.ledger.observe_block(block):
                self._gap(dev, t_ns, loss)
        return self._to_body(dev, block) if self.calibrated else block

    def _gap(self, dev: DeviceRuntime, t_ns: int, loss: Loss) -> None:
        """Frames counted lost before ``dev``'s frame at ``t_ns``: a StreamGap queued for the
        estimators that take it, ahead of that frame (imuhal.core.gaps)."""
        if self.calibrated and self.estimators and self.router.takes(dev.name, StreamGap):
            assert dev.ledger is not None
            self._fusion.append(StreamGap(t_ns=t_ns, device=dev.name,
                                          stream=dev.ledger.channel, frames=loss.frames,
                                          last_ns=loss.last_ns, cause=loss.cause))

    def _to_body(self, dev: DeviceRuntime, block: Block) -> Block:
        """A checked block calibrated and rotated into the body frame; its fusable frames
        are queued for the estimators."""
        if dev.mag_learner is not None and issubclass(block.kind, MagSample):
            self._learn(dev, block.samples())
        # Flagged frames are only rotated, not calibrated.
        block = calibrate_block(block, dev.calibration, dev.chip_to_body_rows,
                                matrix=dev.chip_to_body_array)
        if self.estimators and self.router.takes(block.device, block.kind):
            fused = self._fusable(block)
            if fused is not None:
                self._fusion.append(fused)
                self._blocks_queued = True
        return block

    @staticmethod
    def _fusable(block: Block) -> Block | None:
        """The frames of ``block`` an estimator may take: valid ones and, for a gyro, ones
        clipped at the chip's full scale (:func:`_recovered_clip`)."""
        if not block.flagged:
            return block  # the common case: every frame valid
        f = block.flags
        keep = f == 0
        if issubclass(block.kind, GyroSample):
            keep |= ((f & SampleFlag.SATURATED) != 0) & ((f & ~int(CLIPPED)) == 0)
        return block.select(keep)

    def _learn(self, dev: DeviceRuntime, samples: list[Sample]) -> None:
        """Valid magnetometer frames to the hard-iron learner (sensor frame, raw); a new fit
        becomes the device's magnetometer calibration at once."""
        learner = dev.mag_learner
        assert learner is not None
        for sample in samples:
            if sample.valid and isinstance(sample, MagSample) and learner.feed(sample.mag_ut):
                cal = dev.calibration or DeviceCalibration()
                dev.calibration = cal.model_copy(update={"mag": learner.record(
                    binding=self.calibration_binding(dev.name), date=now())})

    def _fuse(self, before_ns: int | None, reads: bool = False) -> list[Event | AttitudeBlock]:
        """Hand the estimators the queued frames older than ``before_ns`` (all: None), in
        fusion order (the router's rule); returns their estimates, in the order they were
        made (``reads``: the estimates a block step made of a FIFO read's frames as one
        AttitudeBlock, for ``blocks``; else one by one). (A list, not a generator: this
        runs at every poll, and the queue is taken whole, so a consumer that stops
        iterating loses no input.)"""
        out: list[Event | AttitudeBlock] = []
        if not self._blocks_queued:
            # readings only (one-frame blocks kept as their samples): today's queue
            samples = cast("list[Sample]", self._fusion)
            if before_ns is None:
                due, self._fusion = samples, []
            else:
                due = [s for s in samples if s.t_ns < before_ns]
                if not due:
                    return []
                # usually every queued sample is due (they come from earlier polls)
                self._fusion = [] if len(due) == len(samples) else \
                    [s for s in samples if s.t_ns >= before_ns]
            self.router.fuse(due, cast("list[Estimate]", out))
            for teacher in self._teachers:
                teacher.feed(due, cast("list[Estimate]", out))
            return out
        if before_ns is None:
            items, self._fusion = self._fusion, []
        else:
            items = self._due_blocks(before_ns)
        self._blocks_queued = bool(self._fusion)
        if items:
            self.router.fuse_blocks([b if isinstance(b, Block) else Block.of_sample(b)
                                     for b in items], cast("list[Estimate]", out),
                                    estimate_blocks=True)
            if self._teachers or not reads:  # they take estimates one by one
                out = rows_of(out)
            for teacher in self._teachers:
                teacher.feed(items, cast("list[Estimate]", out))
        return out

    def _due_blocks(self, before_ns: int) -> list[Sample | Block]:
        """The queued frames older than ``before_ns`` (a block whose newest frames are not
        is split); the rest stay queued."""
        due: list[Sample | Block] = []
        later: list[Sample | Block] = []
        for item in self._fusion:
            if isinstance(item, Sample):
                (due if item.t_ns < before_ns else later).append(item)
            elif item.t0_ns >= before_ns:
                later.append(item)
            elif int(item.t_ns[-1]) < before_ns:
                due.append(item)
            else:  # a block whose newest frames belong to a later step
                t = item.t_ns
                head, tail = item.select(t < before_ns), item.select(t >= before_ns)
                assert head is not None and tail is not None
                due.append(head)
                later.append(tail)
        self._fusion = later
        return due

    def _learned_status(self) -> dict[str, dict[str, Any]]:
        """Every in-flight learner's status (RunSummary.learned)."""
        out = {n: d.mag_learner.status() for n, d in self.devices.items()
               if d.mag_learner is not None}
        out.update({f"{n} accel": d.accel_teacher.learner.status()
                    for n, d in self.devices.items() if d.accel_teacher is not None})
        return out

    @staticmethod
    def _count_flags(dev: DeviceRuntime, sample: Sample) -> None:
        for flag in SampleFlag:
            if flag and flag in sample.flags:
                dev.flagged[flag.name or str(flag)] += 1

    def run(self, duration_s: float | None, sinks: Sequence[Sink] = ()) -> RunSummary:
        """Run for ``duration_s`` simulated (or real) seconds, feeding every sink.

        Sinks are closed when the run ends or is stopped (KeyboardInterrupt, which the CLI
        also raises for SIGTERM and SIGHUP); when it fails, sinks that have an ``abort()``
        are aborted instead, so a failed run never replaces a good file. A sink that raises
        is aborted (or closed) at once, named in the warnings and left out; the run goes on
        for the others (imuhal.pipeline.containment).
        """
        wall0 = time.perf_counter()
        failed = True
        sink_counts: dict[str, dict[str, int]] = {}
        contained = ContainedSinks(sinks, self.containment, self.registry)
        try:
            if sinks:
                for event in self.events(duration_s):
                    contained.handle(event)
            else:  # nobody takes the frames one by one: a FIFO read stays its blocks
                for _ in self.blocks(duration_s):
                    pass
            failed = False
        except KeyboardInterrupt:
            failed = False
            raise
        finally:
            for sink in sinks:
                if not any(sink is gone for gone in contained.failed):  # those are aborted
                    abort = getattr(sink, "abort", None) if failed else None
                    (abort or sink.close)()
                counts = getattr(sink, "run_counts", None)
                if counts is not None:  # read after closing: a sink may finish sending there
                    sink_counts[getattr(sink, "name", "") or type(sink).__name__] = counts()
        # The span comes from the poll loop, not from reading the clock here: a run and an
        # events() loop then read the clock alike, so either replays a recording of the other.
        summary = self.summary(wall_s=time.perf_counter() - wall0, simulated_s=self.span_s)
        summary.sinks = sink_counts
        return summary

    @property
    def driver_timing(self) -> DriverTiming:
        """What the deadline of a driver call is measured on: the wall clock on a hardware
        board, CPU time on an emulated or replayed one (imuhal.pipeline.containment)."""
        return self._watchdog.timing

    @driver_timing.setter
    def driver_timing(self, timing: DriverTiming) -> None:
        """Measure driver deadlines another way from the next call on (an embedding program
        that wants a shorter bound on a blocked emulated call, or a wall-clock deadline)."""
        self._watchdog.release()
        self._watchdog = Watchdog(timing)

    @property
    def span_s(self) -> float:
        """Seconds (simulated, or real on hardware) the latest run or events() loop has
        covered so far, from its first poll to its latest."""
        first, last = self._span_ns
        return (last - first) / 1e9

    def summary(self, *, wall_s: float = 0.0, simulated_s: float = 0.0) -> RunSummary:
        return RunSummary(
            simulated_s=simulated_s,
            wall_s=wall_s,
            samples={n: d.samples for n, d in self.devices.items()},
            flagged={n: dict(d.flagged) for n, d in self.devices.items()},
            bus_errors={n: d.bus_errors for n, d in self.devices.items()},
            device_errors={n: d.device_errors for n, d in self.devices.items()},
            estimates={e.name: e.outputs for e in self.estimators},
            warnings=list(self.warnings),
            driver={n: d.driver.health.counts() for n, d in self.devices.items()},
            buses=dict(self._bus_modes),
            frames={n: d.ledger.counts() for n, d in self.devices.items()
                    if d.ledger is not None},
            learned=self._learned_status(),
            triggers={n: d.trigger.counts() for n, d in self.devices.items()
                      if isinstance(d.trigger, LineTrigger)},
            contained=self.containment.counts(),
        )

    def close(self) -> None:
        self._watchdog.release()
        for bus in self.buses.values():
            bus.close()
        for line in self._lines.values():
            line.close()

    def __enter__(self) -> Pipeline:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


class _Read:
    """The blocks of one read of several frames (a FIFO read) after validity, calibration
    and rotation, handed out together; ``calibrated``: whether the pipeline calibrated
    when they went through the steps (the start-up phase may switch it on while their
    frames are handed out one by one)."""

    __slots__ = ("blocks", "calibrated", "dev")

    def __init__(self, dev: DeviceRuntime, blocks: list[Block], calibrated: bool) -> None:
        self.dev = dev
        self.blocks = blocks
        self.calibrated = calibrated


class _Expanded:
    """Items of the poll loop with each read's frames one by one (``_read_frames``), as an
    iterator that can say where it stopped: ``rest_of_read`` gives the frames of a read
    part-way handed out (``Pipeline.blocks`` after the start-up phase)."""

    def __init__(self, pipeline: Pipeline,
                 items: Iterator[Event | AttitudeBlock | _Read]) -> None:
        self._pipeline = pipeline
        self._items = items
        self._frames: Iterator[Sample] | None = None

    def __iter__(self) -> _Expanded:
        return self

    def __next__(self) -> Event:
        if self._frames is not None:
            frame = next(self._frames, None)
            if frame is not None:
                return frame
            self._frames = None
        item = next(self._items)
        if type(item) is _Read:
            self._frames = self._pipeline._read_frames(item)
            return next(self._frames)  # a read holds at least one frame
        return cast("Event", item)

    def rest_of_read(self) -> Iterator[Sample]:
        frames, self._frames = self._frames, None
        return frames if frames is not None else iter(())


BUFFERED_SOURCES = frozenset({TimeSource.CHIP_CLOCK, TimeSource.CHIP_FIFO})
"""Time sources of streams read from a chip's FIFO."""


_CROSS_CHECKED = frozenset((Quantity.PRESSURE, Quantity.POSITION, Quantity.VELOCITY))
"""The quantities the vertical cross-check sees (imuhal.pipeline.crosscheck)."""


def _vertical_check(devices: dict[str, DeviceRuntime]) -> VerticalCrossCheck | None:
    """The cross-check of a board with a GNSS receiver (a device stating position or
    velocity) and a barometer (the first device stating pressure); None without both."""
    channels = {name: type(dev.driver).channels for name, dev in devices.items()}
    baro = next((name for name, chs in channels.items() if Quantity.PRESSURE in chs), None)
    gnss = any(Quantity.POSITION in chs or Quantity.VELOCITY in chs
               for chs in channels.values())
    return VerticalCrossCheck(baro) if baro is not None and gnss else None


def _frames(samples: list[Sample]) -> _Readings | list[Block]:
    """A poll's samples as the pipeline hands them out: readings of different streams (a
    register poll) as they are, several of one stream (a FIFO read) as blocks."""
    n = len(samples)
    if n < 2 or (n == 2 and type(samples[0]) is not type(samples[1])) \
            or len({type(s) for s in samples}) == n:  # (a register poll's two: no set built)
        return _Readings(samples)
    return blocks_of(samples)


def _waiter_of(board: Board, clock: Clock, lines: dict[str, TriggerLine],
               recorder: BusRecorder | None) -> Waiter:
    """Where the pipeline waits: on the clock alone, or (a board with lines) on the board's
    waiter, whose edges a recording keeps."""
    if not lines:
        return ClockWaiter(clock)
    # a board with lines provides their waiter (Board's optional part: HardwareBoard,
    # EmulatedBoard, ReplayBoard)
    waiter: Waiter = getattr(board, "waiter")()  # noqa: B009
    if recorder is not None:
        record = recorder.on_edge
        waiter = RecordedWaiter(waiter, lambda device, edge: record(device, edge.t_ns,
                                                                    edge.seqno))
    return waiter


def _fan_out(taps: list[Callable[[Transfer], None]]) -> Callable[[Transfer], None]:
    if len(taps) == 1:
        return taps[0]

    def each(transfer: Transfer) -> None:
        for tap in taps:
            tap(transfer)

    return each
