"""What a chip emulator is: a bus face (register file, state machines) and a physics face.

A driver talks to an emulator only through a bus, exactly as to silicon. The simulation talks
to it only through ``set_physics``, handing it true values in the chip's own sensor frame and
in SI units; the emulator encodes them with the chip's configured range and resolution when
its measurement completes.
"""

from __future__ import annotations

import random
from abc import ABC, abstractmethod
from collections.abc import Callable, Mapping, Sequence
from typing import TYPE_CHECKING, Any, ClassVar

from pydantic import ValidationError

from imuhal.bus.base import BusKind
from imuhal.core.clock import Clock, SimulatedClock
from imuhal.core.samples import Quantity
from imuhal.sim.errors import SensorErrorSpec
from imuhal.sim.inputs import PhysicalInputs, PlannedInputs
from imuhal.sim.measured import MeasuredInstants

if TYPE_CHECKING:
    from imuhal.sim.emulated_bus import EmulatedBus


class ChipEmulator(ABC):
    """Base of every chip emulator.

    ``clock`` is the simulated clock the emulator measures conversion and data-ready timing
    against.

    Fault-injection hook (driven by imuhal.emulation.faults; docs/reliability.md). Generic
    parts, here: ``absent`` makes the chip NACK every transfer; ``frozen`` makes the chip
    keep measuring the physics it had when the freeze began, so it keeps producing the same
    raw words (a hung conversion). Parts each emulator implements where its chip has them:
    ``silent_reset()`` (power-on register state, unannounced), ``stuck_data_ready`` (set
    True: no measurement completes, data-ready never comes; the chip's own soft reset may
    clear it; the class sets ``models_stuck_data_ready``), ``corrupt_trim(rng, bits)`` (flip
    bits of the factory calibration the driver reads), ``stale_solution(time)`` (a
    navigation receiver sends its last solution again, ``time`` "repeated" or "unresolved";
    None ends it). ``chip_faults()`` lists what an emulator class models.
    """

    #: How far past its present a chip with its own clock announces its coming pulls
    #: (:meth:`announce_pulls`; 4 s, 1000 instants at 250 Hz: the scenario's truth costs
    #: about 9 us an instant computed a second at a time, 5 us four seconds at a time, 12
    #: one by one: tests/benchmarks/bench_truths.py).
    PULL_AHEAD_NS: ClassVar[int] = 4_000_000_000

    #: The largest clock error an emulated chip's ``oscillator_error`` accepts (a fraction).
    MAX_OSCILLATOR_ERROR: ClassVar[float] = 0.1

    @classmethod
    def checked_oscillator_error(cls, fraction: float) -> float:
        """``fraction`` when it is a plausible oscillator error (within +-10 %), else a
        ValueError naming it: what every emulator's ``oscillator_error`` setter accepts."""
        if not -cls.MAX_OSCILLATOR_ERROR <= fraction <= cls.MAX_OSCILLATOR_ERROR:
            raise ValueError(f"oscillator_error {fraction} is not a clock error within +-10 %")
        return fraction

    #: The driver name this emulator stands in for (the registry pairs them by it).
    chip: str = ""
    #: The chip's datasheet noise and bias figures that the simulator applies to the truth
    #: before this emulator encodes it; None: an ideal chip. A subclass may give a
    #: :class:`~imuhal.sim.errors.SensorErrorSpec` or a mapping of its fields; the mapping is
    #: validated when the class is defined, so a typo in a plugin fails at import, naming it.
    error_spec: ClassVar[SensorErrorSpec | Mapping[str, Any] | None] = None
    #: Set True by an emulator whose measurement engine honours ``stuck_data_ready``.
    models_stuck_data_ready: ClassVar[bool] = False
    #: False for a chip that measures no motion quantity (a barometer: pressure and
    #: temperature only): an emulated board then hands it a light truth, without the
    #: attitude, body rate, specific force, field and velocity (None in its inputs).
    measures_motion: ClassVar[bool] = True
    #: Opt-in to imuhal's generic conformance sweep, which checks the pair against an
    #: independent table in imuhal's own test data; a third-party emulator leaves it False.
    conformance_sweep: ClassVar[bool] = False
    #: True for an emulator with a clock of its own (issue 25 item 1): it measures at its
    #: own instants and pulls its inputs at each (``pull_physics``), so an emulated board
    #: does not push them at the host's polls.
    pulls_physics: ClassVar[bool] = False
    #: The shortest output period (s) the chip can be configured to: the floor under the
    #: host's poll interval when :meth:`noise_period_s` does not know the chip's own period.
    #: A subclass states its chip's; 1/8 kHz is the fastest common MEMS output rate.
    min_output_period_s: ClassVar[float] = 1.0 / 8000.0
    #: True for an emulator that models its chip's INT pin (:meth:`interrupt_after`,
    #: :meth:`interrupt_pin`): a profile's ``interrupt:`` line is then driven by it.
    models_interrupt: ClassVar[bool] = False

    def __init_subclass__(cls, **kwargs: Any) -> None:
        super().__init_subclass__(**kwargs)
        spec = cls.__dict__.get("error_spec")
        if spec is not None and not isinstance(spec, SensorErrorSpec):
            if not isinstance(spec, Mapping):
                raise TypeError(f"{cls.__name__}.error_spec must be a SensorErrorSpec or a "
                                f"mapping of its fields, not {type(spec).__name__}")
            try:
                cls.error_spec = SensorErrorSpec.model_validate(spec)
            except ValidationError as exc:
                raise TypeError(f"{cls.__name__}.error_spec is not a valid SensorErrorSpec: "
                                f"{exc}") from None

    def __init__(self, clock: Clock | None = None) -> None:
        self.clock: Clock = clock if clock is not None else SimulatedClock()
        self.absent = False
        self.frozen = False
        self.stuck_data_ready = False
        self.host_baudrate = 0
        """Serial chips: the line speed the host's UART is set to (0: not a UART)."""
        self._physics = PhysicalInputs()
        self._physics_later: Callable[[], PhysicalInputs] | None = None
        """Inputs handed over but not yet computed (:meth:`set_physics_later`)."""
        self.planned: tuple[PlannedInputs, int] | None = None
        """(plan, row) while the inputs standing are a row of an emulated board's plan
        kept whole (:meth:`keep_planned`); None otherwise."""
        self.undisturbed: PhysicalInputs | None = None
        """What the chip would measure now had no value fault (``wild_value``,
        ``wrong_pressure``) replaced the world it is handed (set by an emulated board with
        ``physics``; None: nothing replaced it). A chip whose own filter runs on its input
        (imuhal.sim.lowpass) carries the difference into its next outputs."""
        self.physics_t_ns: int | None = None
        """The time ``physics`` is true at, as the emulated board hands it over (a poll that
        comes late gives the world at its due time); None: now."""
        self.physics_at: Callable[[int], None] | None = None
        """Set by the emulated board: hands this chip (``set_physics``) the world at a given
        time. A chip that keeps measuring on its own while its host does not poll it (a GNSS
        receiver, whose device may be recovering) asks for the world at its own epochs;
        register chips are given it at each poll and need not."""
        self.physics_source: Callable[[int], None] | None = None
        """Set by an emulated board for a ``pulls_physics`` emulator: hands the chip its
        inputs at a given instant (ns) through ``set_physics``."""
        self.physics_ahead: Callable[[Sequence[int]], None] | None = None
        """Set by an emulated board beside ``physics_source``: told the instants (ns,
        ascending) at which the chip will pull its inputs, in the order of its pulls (an
        instant it pulls twice given twice), the board computes what it will hand over at
        each in one pass (a chip with its own clock knows its coming instants); it hands
        that out while the pulls come as announced."""
        self.physics_rows: Callable[[Sequence[int]], tuple[PlannedInputs, int] | None] | None \
            = None
        """Set by an emulated board beside ``physics_ahead``: the pulls at the given instants
        (ns, ascending; an instant twice where the chip announced it twice, one pull per
        channel) taken at once, as that many ``physics_source`` calls
        would take them, when every one of them comes from the board's plan as announced:
        returns (plan, row of the first instant), the rows following on, and the last row
        stands as the chip's inputs (``planned``). None when any of them does not (nothing
        is taken then: the chip pulls them one by one). For a chip that latches a FIFO
        fill's measurements, or both channels of an instant, at once on the plan's arrays."""
        self.master_instant_ns: int | None = None
        """Set while a bus master on the chip's own board (the MPU-9250's I2C master)
        performs a transaction it timed itself (``EmulatedBus.transfer_at``): the chip
        answers as at that instant, which may lie before the host's clock (a master
        catching up on the samples its FIFO kept through a host stall)."""
        self.measured_ns = MeasuredInstants()
        """The instants (ns, ascending) at which the chip completed a measurement of the
        stream its driver accounts for, recorded by emulators that model it (issue 25
        item 5: the exact count behind ``frames_between``); kept as runs of the chip's
        period, so its size grows with the breaks of the cadence, not with the run."""

    def pull_physics(self, t_ns: int) -> None:
        """A measurement happens at ``t_ns`` (never before the previous one): take the
        inputs of that instant, when a board provides them (a bare emulator keeps what
        ``set_physics`` gave it)."""
        if self.physics_source is not None:
            self.physics_source(t_ns)

    def announce_pulls(self, first_ns: int, period_ns: int, now_ns: int) -> int:
        """Tell the board (``physics_ahead``) that the chip will pull its inputs at
        ``first_ns``, ``first_ns + period_ns``, ... up to ``PULL_AHEAD_NS`` past ``now_ns``
        (its clock as it stands), so their inputs come from one vectorised pass. Returns the
        last instant announced (-1: no board listens); a pull that comes elsewhere (a rate
        or clock change, a skipped measurement) is computed when it happens."""
        if self.physics_ahead is None or period_ns <= 0:
            return -1
        until = now_ns + self.PULL_AHEAD_NS
        count = max(0, (until - first_ns) // period_ns) + 1
        self.physics_ahead([first_ns + k * period_ns for k in range(count)])
        return first_ns + (count - 1) * period_ns

    def record_measurements(self, first_ns: int, period_ns: int, count: int) -> None:
        """``count`` measurements completed at ``first_ns``, ``first_ns + period_ns``, ..."""
        self.measured_ns.add(first_ns, period_ns, count)

    def frames_between(self, first_stamp_ns: int, last_stamp_ns: int) -> int:
        """Measurements from the one a sample stamped ``first_stamp_ns`` carries (the latest
        completed by then) to the one a sample stamped ``last_stamp_ns`` carries, both
        included: what the chip produced over a span of delivered samples."""
        first = self.measured_ns.count_until(first_stamp_ns)
        last = self.measured_ns.count_until(last_stamp_ns)
        return last - first + 1 if first else last

    def interrupt_after(self, after_ns: int) -> int | None:
        """The first instant after ``after_ns`` (ns, the emulator's clock) at which the chip
        asserts its INT pin, as its registers stand now (an interrupt source enabled, the
        chip awake); None: it will not. Only for ``models_interrupt`` emulators."""
        raise NotImplementedError(f"{type(self).__name__} does not model an INT pin")

    def interrupt_pin(self) -> tuple[bool, int]:
        """(active high, pulse width in ns) of the INT pin as configured: a pulse width of 0
        is a latched pin, held until the host clears the status (its release is not an
        edge the emulator reports)."""
        raise NotImplementedError(f"{type(self).__name__} does not model an INT pin")

    @abstractmethod
    def bus_transfer(self, kind: BusKind, write: bytes, read_len: int) -> bytes:
        """Answer one bus transaction (write then read) as the chip would."""

    def idle_answer(self, kind: BusKind, write: bytes, read_len: int) -> bytes | None:
        """The chip's answer to the read transaction (``write`` then ``read_len`` bytes)
        at its present (:meth:`now_ns`) when giving it changes nothing in the chip (no
        register, pointer, lock or measurement schedule moves, no measurement falls due);
        None when it would, or when the emulator does not tell (this default). A bus
        master on the board (``EmulatedBus.transfer_at``) then hands the answer over
        without carrying out the transaction: a slave auto-read repeating itself between
        the slave's measurements."""
        return None

    def bus_receive(self, kind: BusKind, max_len: int) -> bytes:
        """Byte-stream chips (a UART device): up to ``max_len`` bytes the chip has sent by
        now. Register-mapped chips never send unprompted."""
        return b""

    @property
    def physics(self) -> PhysicalInputs:
        """The true values the chip measures now (sensor frame, SI)."""
        later = self._physics_later
        if later is not None:
            self._physics_later = None
            self._physics = later()
        return self._physics

    @physics.setter
    def physics(self, inputs: PhysicalInputs) -> None:
        self._physics = inputs
        self._physics_later = None
        self.planned = None

    def set_physics(self, inputs: PhysicalInputs) -> None:
        """Hand the emulator the true values it should measure from now on (ignored while
        ``frozen``: the chip keeps converting what it had)."""
        if not self.frozen:
            self.physics = inputs

    def set_physics_later(self, compute: Callable[[], PhysicalInputs]) -> None:
        """:meth:`set_physics` with the inputs ``compute()`` returns, computed only if the
        chip reads them (``physics``) before it is handed others: a chip that measures at a
        few of its host's polls (a barometer starting a conversion) needs the world at
        those only. An emulated board uses it only for an emulator that keeps the base
        class's :meth:`set_physics` (one that acts on new inputs overrides it)."""
        if not self.frozen:
            self._physics_later = compute
            self.planned = None

    def set_planned(self, planned: PlannedInputs, index: int) -> None:
        """:meth:`set_physics` with row ``index`` of inputs an emulated board computed
        ahead for the chip's announced pulls (``physics_ahead``). An emulator may keep the
        plan instead and encode its quantities for every row at once (its counts in one
        numpy pass, by the operations it applies to one value: the same counts), as long
        as ``physics`` reads the row while it stands; this one hands the row over."""
        self.set_physics(planned.row(index))

    def keep_planned(self, planned: PlannedInputs, index: int) -> None:
        """:meth:`set_planned` for an emulator that reads the plan's arrays: the plan and
        the row stand as ``planned`` (until other inputs are handed over) and the row's
        :class:`PhysicalInputs` is made only if ``physics`` is read (ignored while
        ``frozen``, as :meth:`set_physics`)."""
        if not self.frozen:
            self._physics_later = self._planned_row
            self.planned = (planned, index)

    def _planned_row(self) -> PhysicalInputs:
        assert self.planned is not None
        planned, index = self.planned
        return planned.row(index)

    def now_ns(self) -> int:
        """The chip's present: the host's clock, or the instant of a master's timed
        transaction (``master_instant_ns``)."""
        instant = self.master_instant_ns
        return self.clock.now_ns() if instant is None else instant

    # -- conventions every emulator follows where its chip has the feature ----------------

    def resolution(self, channel: Quantity) -> float:
        """SI units per count of ``channel`` in the current configuration."""
        raise NotImplementedError(f"{type(self).__name__} does not report its resolution")

    def full_scale(self, channel: Quantity) -> float:
        """The largest magnitude (SI) ``channel`` can report in the current configuration."""
        raise NotImplementedError(f"{type(self).__name__} does not report its full scale")

    def noise_period_s(self, channel: Quantity) -> float | None:
        """The period (s) of the samples the chip outputs on ``channel`` in its current
        configuration (output data rate, standby plus measurement, conversion time), as the
        datasheet gives it for the configuration registers. The simulator draws white noise
        in the Nyquist band of this period (``noise_density`` specs without a
        ``bandwidth_hz``): a chip's noise depends on its own rate, not on how often the host
        polls it. None: unknown (e.g. a reserved rate code); the simulator then uses the
        time since the previous poll, never below ``min_output_period_s``.

        Like :meth:`noise_bandwidth_hz`, it must follow from the configuration registers
        alone: an emulated board asks again only after a write-only transaction to the chip
        (``read_len`` 0), and at every poll of a device with faults scheduled."""
        return None

    def noise_bandwidth_hz(self, channel: Quantity) -> float | None:
        """The bandwidth (Hz) of the chip's digital low-pass filter on ``channel`` in its
        current configuration (the datasheet's 3 dB bandwidth for the filter setting). The
        simulator draws the noise of ``noise_density`` specs without a ``bandwidth_hz`` in
        the narrower of this band and the Nyquist band of :meth:`noise_period_s`. None: no
        filter narrower than the output's Nyquist band is known."""
        return None

    def silent_reset(self) -> None:
        """Fault injection: the chip resets without telling anyone (configuration lost)."""
        raise NotImplementedError(f"{type(self).__name__} does not model a silent reset")

    def corrupt_trim(self, rng: random.Random, bits: int = 1) -> str:
        """Fault injection: flip ``bits`` random bits of the factory calibration (PROM,
        trimming, sensitivity adjustment) as the driver reads it; what the sensor element
        measures is unchanged. Returns what was changed, for the run's log."""
        raise NotImplementedError(f"{type(self).__name__} has no factory calibration to corrupt")

    def stale_solution(self, time: str | None) -> None:
        """Fault injection (``stale_navigation``): a navigation receiver keeps sending the
        last solution it had, claiming a fix, with that solution's time (``"repeated"``) or
        its running clock's marked not valid (``"unresolved"``); None: it navigates again."""
        raise NotImplementedError(f"{type(self).__name__} is no navigation receiver")

    @classmethod
    def chip_faults(cls) -> frozenset[str]:
        """The chip-level fault kinds this emulator models (imuhal.profile.faults)."""
        kinds = {"frozen"}
        if cls.silent_reset is not ChipEmulator.silent_reset:
            kinds.add("reset")
        if cls.corrupt_trim is not ChipEmulator.corrupt_trim:
            kinds.add("corrupt_trim")
        if cls.models_stuck_data_ready:
            kinds.add("stuck_data_ready")
        if cls.stale_solution is not ChipEmulator.stale_solution:
            kinds.add("stale_navigation")
        return frozenset(kinds)

    def connect_host(self, host_bus: EmulatedBus) -> None:  # noqa: B027 - optional hook
        """Called once the whole board is attached, with the bus this chip sits on. A chip
        with an I2C bypass switch joins its child bus to ``host_bus`` here."""

    def child_buses(self) -> dict[str, EmulatedBus]:
        """Downstream buses this chip masters (e.g. the MAX21100's I2C master), by the same
        local names its driver's ``child_buses`` uses. Emulators of chips behind it are
        attached to these, and this emulator performs real transfers on them."""
        return {}


class HangsBetweenTransfers:
    """For an emulator that brings its measurements up to date at each transfer
    (``_advance``; the next measurement due at ``_next_ns``, None while idle): setting
    ``stuck_data_ready`` brings them up to now first (the fault's ``start_s``: the fault
    injection sets it as at that instant, ``master_instant_ns``), so what fell due before a
    hang began is measured and what fell due while it lasted is not, whatever transfer comes
    next. Put it before :class:`ChipEmulator` among the bases."""

    _hung: bool

    def _advance(self) -> None:
        raise NotImplementedError

    @property
    def stuck_data_ready(self) -> bool:
        """The measurement engine hangs (fault injection): no measurement completes."""
        return self._hung

    @stuck_data_ready.setter
    def stuck_data_ready(self, hung: bool) -> None:
        if hung != getattr(self, "_hung", hung) and self._measurement_due():
            self._advance()
        self._hung = hung

    def _measurement_due(self) -> bool:
        """A measurement is scheduled (``_next_ns`` set; an idle chip has none to bring up
        to date)."""
        return getattr(self, "_next_ns", None) is not None
