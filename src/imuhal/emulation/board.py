"""An emulated board: the profile's buses and chips as register-level emulators, driven by a
simulated scenario on a simulated clock. It is a :class:`~imuhal.pipeline.board.Board`: the
pipeline calls :meth:`EmulatedBoard.before_poll` before each poll, which hands the chip its
inputs at that instant; a chip with a clock of its own (``ChipEmulator.pulls_physics``) is
instead handed its inputs at each of its measurement instants, which it asks for.

The simulation knows the truth in the body frame; each chip sees it in its own sensor frame
(the inverse of its chip -> body rotation), optionally through that chip's error model.

What a chip is handed is computed in numpy for many instants at once where the chip says
when it will pull (``ChipEmulator.physics_ahead``: the truth, rotation and error model of
the coming seconds in one pass, handed out while the pulls come as announced), and only
when it is read for a chip handed it at the host's polls that reads it at a few of them
(``ChipEmulator.set_physics_later``); both give the floats computing it pull by pull gives.
"""

from __future__ import annotations

import functools
import inspect
import threading
from collections.abc import Callable, Iterable, Sequence

import numpy as np

from imuhal.core.clock import SimulatedClock
from imuhal.core.errors import ImuhalError, PluginError
from imuhal.core.frames import FloatArray
from imuhal.core.poll_plan import POLL_PLAN
from imuhal.core.quantities import Quantity
from imuhal.emulation.faults import BoardFaults, FaultLine
from imuhal.emulation.lines import EmulatedLine
from imuhal.pipeline.pipeline import Pipeline
from imuhal.pipeline.triggers import SimulatedWaiter, Waiter
from imuhal.plugins.manager import Registry
from imuhal.profile.faults import FaultSpec
from imuhal.profile.model import BoardProfile
from imuhal.profile.topology import device_order, split_bus_ref
from imuhal.sim.chip import ChipEmulator
from imuhal.sim.emulated_bus import EmulatedBus
from imuhal.sim.errors import ErrorPlan, SensorErrorModel
from imuhal.sim.inputs import NO_OTHER, PhysicalInputs, PlannedInputs
from imuhal.sim.scenario import ChipTruth, Scenario, TruthState
from imuhal.sim.world import chip_other, chip_vectors

DEFAULT_PERIOD_S = 0.004
"""Sample period assumed for a device's first error-model draw (before it has been polled)
when its emulator does not know its own output period."""

_QUANTITY_BY_NAME = {"accel": Quantity.ACCEL, "gyro": Quantity.GYRO, "mag": Quantity.MAG}


class EmulatedBoard:
    def __init__(
        self,
        profile: BoardProfile,
        registry: Registry,
        clock: SimulatedClock,
        scenario: Scenario,
        chip_to_body: dict[str, FloatArray],
        error_models: dict[str, SensorErrorModel] | None = None,
        faults: Iterable[FaultSpec] = (),
        seed: int = 0,
    ) -> None:
        """``faults``: injected faults (imuhal.emulation.faults; the caller passes the
        profile's ``emulation.faults`` and any others); ``seed`` seeds their draws."""
        self.clock = clock
        self.scenario = scenario
        self.poll_plan = POLL_PLAN
        """The drivers' poll plan (imuhal.core.poll_plan; ``open_emulated(poll_plan=)``)."""
        self.buses: dict[str, EmulatedBus] = {}
        for name, cfg in profile.buses.items():
            factory = registry.buses.get(cfg.kind)
            self.buses[name] = EmulatedBus(f"emul://{name}", factory.kind)
        self.emulators: dict[str, ChipEmulator] = {}
        self.faults = BoardFaults(clock, self.emulators, seed=seed)
        hosts: dict[str, EmulatedBus] = {}
        lines: dict[str, FaultLine] = {}
        for name in device_order(profile):
            dev = profile.devices[name]
            reg = registry.emulators.entries.get(dev.driver)
            if reg is None:
                raise PluginError(
                    f"device {name!r}: no emulator is installed for driver {dev.driver!r}, so "
                    f"this profile cannot run emulated; emulators exist for: "
                    f"{', '.join(registry.emulators.names()) or 'none'}"
                )
            try:
                inspect.signature(reg.obj).bind(clock=clock)
            except TypeError:
                raise PluginError(
                    f"device {name!r}: the emulator {reg.obj.__qualname__} registered for "
                    f"{dev.driver!r} by plugin {reg.plugin!r} ({reg.package or 'local'}) cannot "
                    "be built as Emulator(clock=...); its constructor must accept the keyword "
                    "argument clock (see docs/writing-a-driver.md) - update the plugin"
                ) from None
            emulator = reg.obj(clock=clock)
            host = self._bus_for(dev.bus)
            line = self.faults.line(name, emulator, host, dev.address)
            host.attach(dev.address, line)
            self.emulators[name] = emulator
            lines[name] = line
            hosts[name] = host
        for name, emulator in self.emulators.items():
            emulator.connect_host(hosts[name])
        self.lines = self._lines(profile)
        """The data-ready lines the profile's ``interrupt:`` names, by device, driven by
        the chips' INT pin models."""
        for spec in faults:
            self.faults.add(spec)
        self._chip_to_body = chip_to_body
        errors = error_models or {}
        self._devices = {
            name: _Device(emulator, lines[name],
                          np.asarray(chip_to_body[name], dtype=float).tolist(),
                          errors.get(name))
            for name, emulator in self.emulators.items()}
        for name, emulator in self.emulators.items():
            if type(emulator).pulls_physics:
                emulator.physics_source = self._physics_source(name)
                emulator.physics_ahead = functools.partial(self._inputs_ahead, name=name)
                emulator.physics_rows = functools.partial(self._planned_rows, name=name)
            emulator.physics_at = functools.partial(self._give, name=name)
        self._truth_cache: tuple[int, TruthState] | None = None
        """(time, truth) of the latest ``truth_at``: one attribute, replaced whole, so a
        reader on another thread never pairs one time with another time's truth."""
        self._updated_ns: int | None = None
        # The chip truth of the latest instant, full and light (computed once per instant
        # and shared by every chip polled then).
        self._full_ns: int | None = None
        self._full: ChipTruth | None = None
        self._light_ns: int | None = None
        self._light: ChipTruth | None = None
        self._ahead: dict[int, ChipTruth] = {}
        """Full chip truths computed ahead for a chip's coming instants (``_truths_ahead``),
        by time (ns); the same floats as ``scenario.chip_truth`` there."""
        # ``truth`` may be read from another thread (the live view) while the run polls:
        # scenarios fill caches as they go, so one thread at a time evaluates the scenario.
        self._scenario_lock = threading.Lock()

    def _lines(self, profile: BoardProfile) -> dict[str, EmulatedLine]:
        lines = {}
        for name, emulator in self.emulators.items():
            interrupt = profile.devices[name].interrupt
            if interrupt is None:
                continue
            if not type(emulator).models_interrupt:
                raise PluginError(
                    f"devices.{name}.interrupt: the {emulator.chip or type(emulator).__name__} "
                    "emulator models no INT pin, so this line cannot be emulated; remove "
                    "interrupt: to run it emulated (polled)")
            lines[name] = EmulatedLine(f"emul://{name}/INT", emulator, self.clock,
                                       interrupt.edge)
        return lines

    def waiter(self) -> Waiter:
        """The pipeline waits on the simulated clock for the lines' next edges."""
        return SimulatedWaiter(self.clock, self.lines)

    def _physics_source(self, device: str) -> Callable[[int], None]:
        """What a chip with its own clock calls at each of its measurement instants
        (:meth:`update` of that device, without its loop: about 500 pulls a simulated
        second on the seed board)."""
        give = self._give

        def pull(t_ns: int) -> None:
            self._updated_ns = t_ns
            give(t_ns, device)
        return pull

    @staticmethod
    def of(pipeline: Pipeline) -> EmulatedBoard:
        """The emulated board ``pipeline`` polls (typed access to its emulators, scenario and
        truth); an ImuhalError when the pipeline runs on real hardware."""
        board = pipeline.board
        if not isinstance(board, EmulatedBoard):
            raise ImuhalError("this pipeline runs on real hardware, not an emulated board; "
                              "open it with imuhal.emulation.open_emulated")
        return board

    def _bus_for(self, ref: str) -> EmulatedBus:
        parent, child = split_bus_ref(ref)
        if child is None:
            return self.buses[parent]
        provided = self.emulators[parent].child_buses()
        if child not in provided:
            raise PluginError(
                f"the emulator of device {parent!r} provides no bus {child!r} "
                f"(it provides: {', '.join(provided) or 'none'})"
            )
        return provided[child]

    @property
    def truth(self) -> TruthState | None:
        """The scenario's truth at the latest update (None before the first)."""
        if self._updated_ns is None:
            return None
        return self.truth_at(self._updated_ns)

    def truth_at(self, t_ns: int) -> TruthState:
        """The scenario's truth at ``t_ns`` (cached for repeated calls at one time)."""
        cached = self._truth_cache
        if cached is not None and cached[0] == t_ns:
            return cached[1]
        with self._scenario_lock:
            truth = self.scenario.truth(t_ns / 1e9)
        self._truth_cache = (t_ns, truth)
        return truth

    def _chip_truth(self, t_ns: int, motion: bool) -> ChipTruth:
        """The chip truth at ``t_ns`` (light when ``motion`` is False), once per instant."""
        # A full truth of the instant serves a light request as well (same floats).
        if t_ns == self._full_ns:
            return self._full  # type: ignore[return-value]  # set with _full_ns, which matched: not None
        if not motion and t_ns == self._light_ns:
            return self._light  # type: ignore[return-value]  # set with _light_ns, which matched: not None
        ahead = self._ahead.get(t_ns)
        if ahead is not None:
            self._full_ns, self._full = t_ns, ahead
            return ahead
        with self._scenario_lock:
            truth = self.scenario.chip_truth(t_ns / 1e9, motion=motion)
        if motion:
            self._full_ns, self._full = t_ns, truth
        else:
            self._light_ns, self._light = t_ns, truth
        return truth

    def _truths_ahead(self, times_ns: Sequence[int]) -> None:
        """A chip with its own clock will measure at ``times_ns`` (ascending): compute the
        full truth of all of them in one call (``Scenario.chip_truths``, the same floats as
        one by one), kept until the chip measures there. Truths before the first of these
        are dropped (the chip's instants only move on)."""
        if not times_ns:
            return
        first = times_ns[0]
        kept = {t: c for t, c in self._ahead.items() if t >= first}
        todo = [t for t in times_ns if t not in kept]
        if todo:
            with self._scenario_lock:
                truths = self.scenario.chip_truths([t / 1e9 for t in todo])
            kept.update(zip(todo, truths, strict=True))
        self._ahead = kept

    def _inputs_ahead(self, times_ns: Sequence[int], name: str) -> None:
        """The chip of device ``name`` will pull its inputs at ``times_ns`` (ascending; an
        instant it pulls twice given twice): compute what it will be handed at each, all
        in one numpy pass (:meth:`_plan_inputs`), and hand them out at its pulls while
        they come as announced. Where that cannot be planned, the truth of the instants
        is computed ahead (:meth:`_truths_ahead`) and the rest goes pull by pull."""
        dev = self._devices[name]
        dev.plan = None
        if not times_ns:
            return
        if not self._plan_inputs(dev, times_ns):
            self._truths_ahead(sorted(set(times_ns)))

    def _plan_inputs(self, dev: _Device, times_ns: Sequence[int]) -> bool:
        """What :meth:`_give` would hand the device's chip at each of ``times_ns``, one
        call after another: the truth (``Scenario.chip_truth_columns``), rotated into the
        chip's frame and through its error model (``SensorErrorModel.plan_values``), each
        by the same operations in the same order on arrays, so the same floats. False
        (nothing planned) for what this does not cover: a chip measuring no motion, faults
        on the device, noise periods that follow the host's polls, truth with plugin
        quantities, times before the device's last inputs."""
        model = dev.model
        if (not dev.motion or self.faults.has_faults(dev.name)
                or (dev.last_t_ns is not None and times_ns[0] < dev.last_t_ns)):
            return False
        periods = None
        if model is not None and model.period_channels:
            periods = self._noise_periods(dev, DEFAULT_PERIOD_S)
            if dev.periods is None:  # they depend on the poll interval
                return False
        unique = np.unique(np.asarray(times_ns, dtype=np.int64))
        with self._scenario_lock:
            columns = self.scenario.chip_truth_columns((unique / 1e9).tolist())
        if columns is None:
            return False
        rows = np.searchsorted(unique, np.asarray(times_ns, dtype=np.int64))
        mount = dev.mount
        force, rate, field = (_rotate_rows(c[rows], mount) for c in (
            columns.specific_force_body_m_s2, columns.angular_rate_body_rad_s,
            columns.magnetic_field_body_ut))
        pressure, temperature = columns.pressure_pa[rows], columns.temperature_degc[rows]
        errors = None
        if model is not None:
            t_s = np.asarray(times_ns, dtype=np.int64) / 1e9
            errors = model.plan_values(t_s, force, rate, field, pressure, temperature,
                                       DEFAULT_PERIOD_S, periods)
            if errors is None:
                return False
            force, rate, field, pressure, temperature = errors.values  # type: ignore[assignment]  # given arrays, it returns arrays
        # Handed to the chip as arrays (``ChipEmulator.set_planned``): one inputs object per
        # pull cost more than the rest of the plan.
        dev.plan = _InputsPlan(
            list(times_ns),
            PlannedInputs(force, rate, field, pressure, temperature,
                          columns.position_ned_m[rows], columns.velocity_ned_m_s[rows]),
            errors, periods, dev.line.writes)
        return True

    def before_poll(self, t_ns: int, device: str) -> int:
        """The pipeline is about to poll ``device``, due at ``t_ns``: apply the faults due
        (a late poll moves the clock) and give its chip its inputs. Returns the time the
        poll actually happens: not before the clock (a poll that fell due while the
        pipeline's thread was held happens, and its chip measures, when it is free)."""
        t_ns = self.faults.before_poll(device, max(t_ns, self.clock.now_ns()))
        if self.emulators[device].physics_source is None:
            # a chip with its own clock pulls its inputs when it measures (what update()
            # does for one device)
            self._updated_ns = t_ns
            self._give(t_ns, device)
        return t_ns

    def _noise_periods(self, dev: _Device, poll_period_s: float) -> dict[str, float]:
        """Per noise-density channel of the device's error model, the sample period (s) its
        noise band follows: the chip's configured output period, else the poll interval
        ``poll_period_s`` floored at the shortest period the chip supports (a poll right
        after another must not widen the band past anything the chip can output); longer
        where the chip's low-pass filter (:meth:`ChipEmulator.noise_bandwidth_hz`) is
        narrower than that period's Nyquist band.

        What the emulator says about its configuration is kept until the next write-only
        transaction on the device's line (``FaultLine.writes``: a chip's configuration
        changes only through them) or, on a device with faults scheduled (a chip reset
        changes it without one), asked at every poll."""
        writes = dev.line.writes
        terms = dev.period_terms
        if terms is None or writes != dev.period_writes or self.faults.has_faults(dev.name):
            terms = dev.period_terms = self._period_terms(dev)
            dev.period_writes = writes
            dev.periods = None
        if dev.periods is not None:
            return dev.periods
        periods: dict[str, float] = {}
        fixed = True
        for channel, own, floor, filtered in terms:
            if own is None:
                fixed = False
                period = max(poll_period_s, floor)
            else:
                period = own
            # The chip's low-pass filter narrows the band below Nyquist: the period whose
            # Nyquist band is the filter's bandwidth.
            if filtered is not None:
                period = max(period, filtered)
            periods[channel] = period
        if fixed:  # the same at every poll until the configuration changes
            dev.periods = periods
        return periods

    @staticmethod
    def _period_terms(dev: _Device) -> tuple[tuple[str, float | None, float, float | None], ...]:
        """(channel, the chip's own output period or None, the floor under the poll
        interval, the period of the filter's band or None) per period channel."""
        emulator = dev.emulator
        floor = emulator.min_output_period_s
        terms = []
        assert dev.model is not None
        for channel in dev.model.period_channels:
            quantity = _QUANTITY_BY_NAME[channel]
            own = emulator.noise_period_s(quantity)
            bandwidth_hz = emulator.noise_bandwidth_hz(quantity)
            terms.append((channel, own if own is not None and own > 0 else None, floor,
                          0.5 / bandwidth_hz if bandwidth_hz is not None and bandwidth_hz > 0
                          else None))
        return tuple(terms)

    def update(self, t_ns: int, device: str | None = None) -> None:
        """Hand ``device`` (default: every chip) its inputs at ``t_ns``: the truth in its
        sensor frame, through its error model when the board has one for it. The error
        model's noise bandwidth follows the chip's own output period
        (:meth:`ChipEmulator.noise_period_s`), not how often the host polls; where the
        emulator does not know it, the time since that device's previous update, never
        below the chip's ``min_output_period_s``.
        A chip that measures no motion (``ChipEmulator.measures_motion``) gets a light
        truth: pressure, temperature and position only."""
        self._updated_ns = t_ns
        for name in (self.emulators if device is None else (device,)):
            self._give(t_ns, name)

    def _give(self, t_ns: int, name: str) -> None:
        """Hand the chip of device ``name`` its inputs at ``t_ns`` (what :meth:`update` does
        per device; also the chips' ``physics_at``, which leaves the board's own time)."""
        dev = self._devices[name]
        plan = dev.plan
        if plan is not None:
            index = self._planned(dev, plan, t_ns)
            if index is not None:
                dev.last_t_ns = t_ns
                dev.emulator.physics_t_ns = t_ns
                dev.emulator.set_planned(plan.inputs, index)
                return
        if dev.later and not self.faults.has_faults(name):
            model = dev.model
            finish = None if model is None else model.apply_later(t_ns / 1e9)
            dev.last_t_ns = t_ns
            dev.emulator.physics_t_ns = t_ns
            dev.emulator.set_physics_later(
                functools.partial(self._inputs_later, dev, t_ns, finish))
            return
        truth = self._chip_truth(t_ns, dev.motion)
        mount = dev.mount
        force, rate, field = chip_vectors(truth, mount)
        other = chip_other(truth, mount) if truth.other else NO_OTHER
        pressure, temperature = truth.pressure_pa, truth.temperature_degc
        model = dev.model
        if model is not None:
            last = dev.last_t_ns
            period = (t_ns - last) / 1e9 if last is not None and t_ns > last \
                else DEFAULT_PERIOD_S
            periods = self._noise_periods(dev, period) if model.period_channels else None
            force, rate, field, pressure, temperature = model.apply_values(  # type: ignore[assignment]  # apply_values returns None only where it was given None, as here it was not
                t_ns / 1e9, force, rate, field, pressure, temperature, period, periods)
        # One inputs object per chip and poll, built through its slots (building one
        # costs more than the error model's arithmetic).
        inputs = PhysicalInputs.build(
            force, rate, field, pressure, temperature, truth.position_ned_m,
            truth.velocity_ned_m_s, other)
        struck = self.faults.physics(name, t_ns, inputs)
        dev.last_t_ns = t_ns
        emulator = dev.emulator
        # the time the inputs are true at: a late poll hands over its due time's world
        emulator.physics_t_ns = t_ns
        # a frozen chip keeps what it had: nothing new reaches its filter
        emulator.undisturbed = inputs if struck is not inputs and not emulator.frozen \
            else None
        emulator.set_physics(struck)

    def _inputs_later(self, dev: _Device, t_ns: int,
                      finish: Callable[[float, float], tuple[float, float]] | None
                      ) -> PhysicalInputs:
        """What :meth:`_give` hands the chip at ``t_ns``, computed when the chip reads it
        (``ChipEmulator.set_physics_later``); ``finish``: the error model's half of the
        call (``SensorErrorModel.apply_later``), whose draws were taken at ``t_ns``."""
        truth = self._chip_truth(t_ns, dev.motion)
        # A chip measuring no motion gets none (read later, the instant's truth may be a
        # full one another chip's pull computed since)
        force, rate, field = chip_vectors(truth, dev.mount) if dev.motion else (None, None, None)
        other = chip_other(truth, dev.mount) if truth.other else NO_OTHER
        pressure, temperature = truth.pressure_pa, truth.temperature_degc
        if finish is not None:
            pressure, temperature = finish(pressure, temperature)
        return PhysicalInputs.build(force, rate, field, pressure, temperature,
                                    truth.position_ned_m, truth.velocity_ned_m_s, other)

    def _planned_rows(self, times_ns: Sequence[int], name: str
                      ) -> tuple[PlannedInputs, int] | None:
        """The chip of device ``name`` pulls its inputs at each of ``times_ns`` (ascending)
        at once (``ChipEmulator.physics_rows``): what ``len(times_ns)`` calls of its
        ``physics_source`` would do when each comes from the plan (:meth:`_planned`), taken
        in one step, the last row left standing; (plan, first row). None, taking nothing,
        when any would not: no plan, instants other than the plan's next, faults on the
        device, or a configuration write since the plan's periods were checked (the pulls
        one by one check them)."""
        dev = self._devices[name]
        plan = dev.plan
        if plan is None or dev.line.writes != plan.writes or self.faults.has_faults(name):
            return None
        first = plan.next
        end = first + len(times_ns)
        if not times_ns or plan.times_ns[first:end] != list(times_ns):
            return None
        plan.next = end
        if plan.errors is not None:
            plan.errors.used = end
        last = times_ns[-1]
        self._updated_ns = last
        dev.last_t_ns = last
        emulator = dev.emulator
        emulator.physics_t_ns = last
        emulator.set_planned(plan.inputs, end - 1)
        return plan.inputs, first

    def _planned(self, dev: _Device, plan: _InputsPlan, t_ns: int) -> int | None:
        """The plan's row of the device's next pull when it comes at ``t_ns`` as
        announced and nothing the plan assumed has changed (its noise periods, the faults
        on it); else None, and the plan is dropped (the error model keeps the calls taken
        from it: ``ErrorPlan.used``)."""
        i = plan.next
        if i < len(plan.times_ns) and plan.times_ns[i] == t_ns \
                and not self.faults.has_faults(dev.name):
            writes = dev.line.writes
            if writes != plan.writes:  # a configuration write: are the periods the same?
                model = dev.model
                periods = None if model is None or not model.period_channels else \
                    self._noise_periods(dev, DEFAULT_PERIOD_S)
                if periods != plan.periods or (periods is not None and dev.periods is None):
                    dev.plan = None
                    return None
                plan.writes = writes
            plan.next = i + 1
            if plan.errors is not None:
                plan.errors.used = i + 1
            return i
        dev.plan = None
        return None


def _rotate_rows(v: np.ndarray, m: list[list[float]] | None) -> np.ndarray:
    """:func:`imuhal.sim.world.chip_vectors`' rotation (``M^T v`` from +0.0, the same
    operations in the same order) on (n, 3) rows."""
    if m is None:
        return v
    (a, b, c), (d, e, f), (g, h, i) = m
    x, y, z = v[:, 0], v[:, 1], v[:, 2]
    return np.stack([0.0 + a * x + d * y + g * z, 0.0 + b * x + e * y + h * z,
                     0.0 + c * x + f * y + i * z], axis=1)


class _InputsPlan:
    """A chip's inputs computed ahead for its announced pulls (``EmulatedBoard._plan_inputs``)."""

    __slots__ = ("errors", "inputs", "next", "periods", "times_ns", "writes")

    def __init__(self, times_ns: list[int], inputs: PlannedInputs,
                 errors: ErrorPlan | None, periods: dict[str, float] | None,
                 writes: int) -> None:
        self.times_ns = times_ns
        self.inputs = inputs
        self.errors = errors
        """The error model's share (its ``used`` follows ``next``)."""
        self.periods = periods
        """The noise periods the error model was planned with."""
        self.writes = writes
        """The device line's write count when they were last checked."""
        self.next = 0
        """The index of the next pull's inputs."""


class _Device:
    """What the per-poll path keeps of one emulated device."""

    __slots__ = (
        "emulator",
        "last_t_ns",
        "later",
        "line",
        "model",
        "motion",
        "mount",
        "name",
        "period_terms",
        "period_writes",
        "periods",
        "plan",
    )

    def __init__(self, emulator: ChipEmulator, line: FaultLine,
                 mount: list[list[float]] | None, model: SensorErrorModel | None) -> None:
        self.emulator = emulator
        self.line = line
        self.name = line.device
        self.mount = mount
        """The chip -> body rotation as nested lists (plain floats rotate three components
        faster than numpy); None: aligned with the body."""
        self.motion = type(emulator).measures_motion
        self.model = model
        self.last_t_ns: int | None = None
        """The previous update's time."""
        self.period_terms: tuple[tuple[str, float | None, float, float | None], ...] | None \
            = None
        self.period_writes = -1
        self.periods: dict[str, float] | None = None
        """The noise periods, while they do not depend on the poll interval."""
        self.plan: _InputsPlan | None = None
        """The chip's inputs computed ahead for its coming pulls, if any."""
        kind = type(emulator)
        self.later = (not kind.pulls_physics and kind.set_physics is ChipEmulator.set_physics
                      and (model is None or model.scalar_only))
        """Whether the chip's inputs may be computed when it reads them: a chip handed
        them at the host's polls that does not act on them when handed
        (``ChipEmulator.set_physics_later``), with an error model that can take its
        draws first (``SensorErrorModel.apply_later``)."""
