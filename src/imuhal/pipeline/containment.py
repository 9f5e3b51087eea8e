"""Plugin containment: whatever a driver, estimator or sink plugin does wrong stays with it.

* An exception from an estimator's ``process`` skips that input for that estimator only; an
  estimate that is not finite or not normalisable is replaced by a
  :class:`~imuhal.estimation.outputs.RejectedEstimate` (flags, no value), so no sink and no
  downstream estimator ever sees its numbers (one the estimator withholds itself,
  ``UNSETTLED``, passes as it is). An estimator that takes more than half the
  real time of its input is reported once, with its cost per sample.
* An exception from a driver that is not an :class:`~imuhal.core.errors.ImuhalError` (a
  plugin's bug: ``ValueError``, ``IndexError``, ...) is a device error: counted, named, the
  device recovered with the usual backoff. A driver call that does not return within its
  deadline (:func:`driver_deadline_s`, from the chip's rate) is interrupted by
  :class:`Watchdog` and its device isolated: never polled again in this run. On a board
  whose time is the host's (hardware) the deadline is wall-clock time; on an emulated or
  replayed board it is the process's CPU time, with a long wall-clock bound for a call
  that blocks (:class:`DriverTiming`), so a starved host does not change a run's figures.
* An exception from a sink disables that sink (a file sink is aborted: its rows stay beside
  the previous file, which is kept); the other sinks go on.

Each failure is counted (:meth:`Containment.counts`, in the run summary) and reported in
one line naming the plugin, its distribution and version. A plugin instance that fails
``DISABLE_AFTER_FAILURES`` times within ``FAILURE_WINDOW_NS`` of data time is disabled for
the rest of the run (docs/reliability.md, "Plugin containment").
"""

from __future__ import annotations

import importlib
import math
import signal
import threading
import time
from collections import Counter, deque
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, field
from types import FrameType
from typing import Any

from imuhal.core.blocks import Block
from imuhal.core.clock import MonotonicClock
from imuhal.core.samples import Sample
from imuhal.core.streams import StreamSpec
from imuhal.estimation.base import Estimator
from imuhal.estimation.outputs import (
    AttitudeBlock,
    Estimate,
    EstimateFlag,
    RejectedEstimate,
    estimate_flags,
    estimate_kind,
    refused_estimate,
    usable_blocks_kept,
)
from imuhal.plugins.manager import Registry, plugin_origin
from imuhal.sinks.base import Event, Sink

DISABLE_AFTER_FAILURES = 10
"""Failures of one plugin instance within FAILURE_WINDOW_NS that disable it."""
FAILURE_WINDOW_NS = 10_000_000_000
"""The window (data time, 10 s) in which DISABLE_AFTER_FAILURES failures disable a plugin."""
SLOW_LOAD = 0.5
"""An estimator whose computing time exceeds this fraction of the data time it processed
(in two consecutive SLOW_WINDOW_NS windows after the first) is reported as slow."""
SLOW_WINDOW_NS = 1_000_000_000
"""The data-time window over which an estimator's computing load is measured (1 s)."""
DEADLINE_PERIODS = 10
"""A driver call must return within this many periods of its slowest stream..."""
DEADLINE_MIN_S = 1.0
"""...and at least this long (s): a recovery may wait for a chip's reset on a real board."""
DEADLINE_NO_STREAM_S = 2.0
"""The deadline (s) of a device whose streams are not known yet (not configured)."""
BLOCKED_WALL_S = 60.0
"""Emulated and replayed boards: a driver call that has not returned after this long on
the wall clock is cut off even though it used little CPU time (it blocks: a sleep, a lock,
a read that never completes). Long, so that a host that starves a niced run of the CPU
for that long is the only way a call of normal cost reaches it."""
TICKS_PER_DEADLINE = 4
"""Emulated and replayed boards: the watchdog's timers tick this many times per
DEADLINE_MIN_S of CPU time and per ``blocked_wall_s`` on the wall clock (:class:`Watchdog`);
a call is cut off at most two ticks after its deadline."""

Warn = Callable[[str], None]


@dataclass
class PluginFaults:
    """What one plugin instance (an estimator instance, a device's driver, a sink) did wrong
    in a run, and whether it is disabled."""

    label: str
    """How the run names the instance, e.g. ``estimator 'ahrs'``."""
    origin: str
    """The plugin it comes from (``plugin_origin``)."""
    counts: Counter[str] = field(default_factory=Counter)
    disabled: bool = False
    recent: deque[int] = field(default_factory=lambda: deque(maxlen=DISABLE_AFTER_FAILURES))
    """Data times (ns) of the latest failures."""
    warned: set[str] = field(default_factory=set)

    @property
    def name(self) -> str:
        return f"{self.label} ({self.origin})"

    def failed(self, t_ns: int, key: str, message: str, warn: Warn) -> bool:
        """Count one failure of kind ``key`` at data time ``t_ns``; the first of each kind is
        reported (``message`` follows the instance's name). Returns True when this failure
        disables the instance."""
        self.counts[key] += 1
        if key not in self.warned:
            self.warned.add(key)
            warn(f"{self.name} {message}")
        recent = self.recent
        recent.append(t_ns)
        if self.disabled or len(recent) < DISABLE_AFTER_FAILURES \
                or recent[-1] - recent[0] > FAILURE_WINDOW_NS:
            return False
        self.disable(f"after {DISABLE_AFTER_FAILURES} failures within "
                     f"{FAILURE_WINDOW_NS / 1e9:g} s", warn)
        return True

    def disable(self, why: str, warn: Warn) -> None:
        self.disabled = True
        self.counts["disabled"] = 1
        warn(f"{self.name} disabled {why}; the run goes on without it")


class Containment:
    """Every plugin instance's faults in one run, by label; warnings go to ``warn``."""

    def __init__(self, warn: Warn) -> None:
        self.warn = warn
        self.records: dict[str, PluginFaults] = {}

    def record(self, label: str, origin: str) -> PluginFaults:
        faults = self.records.get(label)
        if faults is None:
            faults = self.records[label] = PluginFaults(label, origin)
        return faults

    def counts(self) -> dict[str, dict[str, int]]:
        """Per plugin instance that failed at least once: its counts (run summary)."""
        return {label: dict(f.counts) for label, f in self.records.items() if f.counts}


def describe_exception(exc: BaseException) -> str:
    """``Type: message`` on one line."""
    text = " ".join(str(exc).split())
    return f"{type(exc).__name__}: {text}" if text else type(exc).__name__


class EstimatorGuard:
    """Runs one estimator instance contained (see the module docstring)."""

    __slots__ = (
        "_calls",
        "_slow_windows",
        "_spent_ns",
        "_window_start_ns",
        "_windows",
        "estimator",
        "faults",
        "warn",
    )

    def __init__(self, estimator: Estimator, faults: PluginFaults, warn: Warn) -> None:
        self.estimator = estimator
        self.faults = faults
        self.warn = warn
        self._window_start_ns: int | None = None
        self._spent_ns = 0
        self._calls = 0
        self._slow_windows = 0
        self._windows = 0

    def process(self, item: Sample | Estimate) -> list[Estimate]:
        """The estimator's estimates for ``item``, each checked; [] when it is disabled or
        raised."""
        return self._called(item.t_ns, self.estimator.process, item)

    def process_block(self, block: Block) -> list[Estimate]:
        """The estimator's estimates for the frames of ``block`` (``update_block``), each
        checked; [] when it is disabled or raised (the block is skipped for it alone)."""
        return self._called(int(block.t_ns[-1]), self.estimator.update_block, block)

    def process_blocks(self, blocks: Sequence[Block]) -> list[Estimate]:
        """The estimator's estimates for the frames of one fusion step's ``blocks``
        (``update_blocks``), each checked; [] when it is disabled or raised (the step is
        skipped for it alone)."""
        return self._called(max(int(b.t_ns[-1]) for b in blocks),
                            self.estimator.update_blocks, blocks)

    def estimate_blocks(self, blocks: Sequence[Block]) -> list[Estimate | AttitudeBlock]:
        """``process_blocks`` with the estimator's AttitudeBlocks kept whole
        (``Estimator.estimate_blocks``) when every row passes the check; a block with a row
        that does not is checked row by row as ``process_blocks`` checks it."""
        return self._called(max(int(b.t_ns[-1]) for b in blocks),
                            self.estimator.estimate_blocks, blocks)

    def process_estimate_block(self, block: AttitudeBlock) -> list[Estimate]:
        """The estimator's estimates for an upstream AttitudeBlock's rows
        (``Estimator.update_estimate_block``), each checked; [] when it is disabled or
        raised (the block is skipped for it alone)."""
        return self._called(int(block.t_ns[-1]), self.estimator.update_estimate_block, block)

    def _called(self, t_ns: int, call: Callable[[Any], Iterable[Any]],
                arg: object) -> list[Any]:
        if self.faults.disabled:
            return []
        t0 = time.perf_counter_ns()
        try:
            got = call(arg)
            made = got if type(got) is list else list(got or ())  # any iterable
        except Exception as exc:  # a plugin's failure is its own (module docstring)
            self.faults.failed(t_ns, "exceptions",
                               f"raised {describe_exception(exc)} at t={t_ns / 1e9:.3f} s; "
                               "that input is skipped for it alone", self.warn)
            return []
        spent_ns = time.perf_counter_ns() - t0
        start = self._window_start_ns
        if start is not None and t_ns - start < SLOW_WINDOW_NS:
            # _timed inside its window (nearly every call), written out
            self._spent_ns += spent_ns
            self._calls += 1
        else:
            self._timed(t_ns, spent_ns)
        if not made:
            return []
        if AttitudeBlock in map(type, made):  # (no generator set up per call)
            made = usable_blocks_kept(made)
        for i, estimate in enumerate(made):
            if type(estimate) is AttitudeBlock:
                continue  # every row passed (above)
            flags = estimate_flags(estimate) if isinstance(estimate, Estimate) else None
            if flags == EstimateFlag.UNSETTLED and type(estimate) is RejectedEstimate:
                continue  # withheld by its estimator: its own judgement, not a failure
            if flags:
                made[i] = self._rejected(estimate, flags)
            elif flags is None:
                return self._not_estimates(t_ns, estimate)
        return made

    def _rejected(self, estimate: Estimate, flags: EstimateFlag) -> RejectedEstimate:
        kind = estimate_kind(estimate)
        why = " and ".join((f.name or "").lower().replace("_", " ") for f in EstimateFlag
                           if f in flags)
        self.faults.failed(estimate.t_ns, f"rejected_{kind}_estimates",
                           f"made {'an' if kind[:1] in 'aeiou' else 'a'} {kind} estimate that is "
                           f"{why} at "
                           f"t={estimate.t_ns / 1e9:.3f} s; refused (flags {int(flags)}), "
                           "no sink gets its values", self.warn)
        return refused_estimate(estimate, flags, type(self.estimator).name)

    def _not_estimates(self, t_ns: int, thing: object) -> list[Estimate]:
        self.faults.failed(t_ns, "exceptions",
                           f"returned {type(thing).__name__}, not an Estimate, at "
                           f"t={t_ns / 1e9:.3f} s; its output is dropped", self.warn)
        return []

    def _timed(self, t_ns: int, spent_ns: int) -> None:
        """Add one call's cost; at the end of each data-time window, judge the load. The
        first window is not judged (a compiled kernel may compile at its first call)."""
        start = self._window_start_ns
        if start is None:
            self._window_start_ns = t_ns
            return
        self._spent_ns += spent_ns
        self._calls += 1
        span_ns = t_ns - start
        if span_ns < SLOW_WINDOW_NS:
            return
        load = self._spent_ns / span_ns
        self._windows += 1
        self._slow_windows = self._slow_windows + 1 if load > SLOW_LOAD and self._windows > 1 \
            else 0
        if self._slow_windows == 2 and "slow" not in self.faults.warned:
            self.faults.warned.add("slow")
            self.faults.counts["slow_reports"] += 1
            per_s = self._calls / (span_ns / 1e9)
            self.warn(f"{self.faults.name} is slow: {self._spent_ns / self._calls / 1e6:.2f} ms "
                      f"per input, {per_s:.0f} inputs per second of data: {load:.2f} s of "
                      "computing per second of data (a --realtime run falls behind beyond "
                      "1 s; reported once)")
        self._window_start_ns, self._spent_ns, self._calls = t_ns, 0, 0


def driver_deadline_s(streams: Sequence[StreamSpec]) -> float:
    """How long (s) one call of a device's driver may take: DEADLINE_PERIODS periods of its
    slowest stream, at least DEADLINE_MIN_S; DEADLINE_NO_STREAM_S before its streams are
    known."""
    if not streams:
        return DEADLINE_NO_STREAM_S
    return max(DEADLINE_MIN_S, DEADLINE_PERIODS / min(s.rate_hz for s in streams))


@dataclass(frozen=True)
class DriverTiming:
    """What a driver call's deadline is measured on.

    ``cpu`` False (a hardware board: its time is the host's): the wall clock, since a chip
    that does not answer in time on a real board is late whatever the reason. True (an
    emulated or replayed board, whose time is simulated): the process's CPU time (user and
    system, ``ITIMER_PROF``), so a run's figures do not depend on how loaded the host is; a
    call that blocks without using CPU time is cut off after ``blocked_wall_s`` on the wall
    clock (``ITIMER_REAL``)."""

    cpu: bool = False
    blocked_wall_s: float = BLOCKED_WALL_S

    def describe(self, deadline_s: float) -> str:
        """The deadline as a warning states it."""
        if not self.cpu:
            return f"{deadline_s:g} s (from its chip's rate)"
        return (f"{deadline_s:g} s of CPU time (from its chip's rate; an emulated or "
                f"replayed board), or {self.blocked_wall_s:g} s on the wall clock")


def driver_timing(board: object) -> DriverTiming:
    """CPU time for a board whose clock is not the host's (an emulated board's simulated
    clock, a replay's recorded one), the wall clock for one on the host's monotonic clock
    (a hardware board)."""
    return DriverTiming(cpu=not isinstance(getattr(board, "clock", None), MonotonicClock))


class DriverDeadline(BaseException):
    """Raised inside a driver call that overran its deadline (by :class:`Watchdog`). A
    BaseException, so that a driver's ``except Exception`` does not swallow it."""


try:
    # the C function signal.getsignal wraps: the handler as installed, without converting
    # it to a ``signal.Handlers`` member (the conversion fails by an exception for a Python
    # handler and costs about 6 us; ``arm`` asks twice per IMU sample on the hardware path)
    _current_handler: Callable[[int], Any] = importlib.import_module("_signal").getsignal
except ImportError:  # an interpreter without CPython's _signal module
    _current_handler = signal.getsignal


class Watchdog:
    """Interrupts a driver call that overran its deadline: a signal whose handler raises
    :class:`DriverDeadline` in the call.

    On the wall clock (a hardware board) a one-shot ``ITIMER_REAL`` of the deadline is armed
    around each call and cancelled after it (SIGALRM), so the signal never arrives but in an
    overrunning call: a signal interrupts the blocking system call in progress, and on real
    buses a stray one would turn a transfer into a bus error.

    On CPU time (``DriverTiming.cpu``: an emulated or replayed board, whose buses answer in
    the process) the timers tick instead: a periodic ``ITIMER_PROF`` every
    ``DEADLINE_MIN_S / TICKS_PER_DEADLINE`` s of CPU time and a periodic ``ITIMER_REAL``
    every ``blocked_wall_s / TICKS_PER_DEADLINE`` s, started at the first call and stopped
    by :meth:`release`. A call counts the ticks that arrive while it runs; n ticks of one
    timer mean at least n - 1 of its periods spent in the call, so the call is cut off at
    the tick that makes its deadline certain: after the deadline and before the deadline
    plus two periods (1 s of CPU time: cut off between 1 and 1.5 s). Arming and disarming
    then make no system call and write no class attribute: 0.5-0.6 us of CPU per driver
    call against 5 for the four ``setitimer`` calls of one-shot timers (1.8 while the state
    was kept on the class), at about two driver calls per IMU sample on the seed board
    (``python -m tests.benchmarks.bench_block_parts watchdog``, load 10; docs/performance.md,
    "The hardware path's per-poll costs" and "Session 21").

    Why not a worker thread per call: a thread cannot be stopped, so the overrun call would
    go on using the bus beside the next device's transfers, and every poll would pay a thread
    handoff. The signal interrupts Python code and blocking system calls (the call then sees
    the exception); it cannot interrupt a call stuck inside the kernel uninterruptibly. It
    works only in the main thread and when nobody else handles the signals it needs (SIGALRM;
    SIGPROF too on CPU time: a profiler may hold it): otherwise (a pipeline run in a thread)
    ``arm`` returns False and calls are not timed. Every pipeline shares the one handler
    (only one driver call runs at a time in the main thread); the timers and the tick counts
    are process-wide, hence kept in one module-level :class:`_Timers` (not on the class:
    writing a class attribute invalidates the type's attribute caches, and arming wrote
    four at every driver call).
    """

    def __init__(self, timing: DriverTiming | None = None) -> None:
        self.timing = timing if timing is not None else DriverTiming()
        self._signals = (signal.SIGALRM, signal.SIGPROF) if self.timing.cpu \
            else (signal.SIGALRM,)
        self._installed = False
        self._periods = (self.timing.blocked_wall_s / TICKS_PER_DEADLINE,
                         DEADLINE_MIN_S / TICKS_PER_DEADLINE)
        self._tick_limits: dict[float, tuple[int, int]] = {}

    def arm(self, seconds: float) -> bool:
        """Start timing a driver call; False when this thread cannot be interrupted."""
        if not self._handled() and not self._install():
            return False
        timers = _TIMERS
        if self.timing.cpu:
            if timers.ticking != self._periods:
                self._tick()
            limits = self._tick_limits.get(seconds)
            if limits is None:
                limits = self._tick_limits[seconds] = self._limits_for(seconds)
            timers.limits = limits
            timers.wall_ticks = timers.cpu_ticks = 0
        else:
            if timers.ticking is not None:
                Watchdog._stop_ticking()
            signal.setitimer(signal.ITIMER_REAL, seconds)
        timers.active = True
        return True

    def disarm(self) -> None:
        _TIMERS.active = False
        if not self.timing.cpu:
            signal.setitimer(signal.ITIMER_REAL, 0)

    def pause(self) -> None:
        """Stop the ticking timers until the next call (a run loop ended: no tick then
        interrupts what the program does between runs)."""
        _TIMERS.active = False
        Watchdog._stop_ticking()

    def release(self) -> None:
        """Stop the timers and give the signals back to the default handler this watchdog
        found."""
        if self._installed:
            _TIMERS.active = False
            signal.setitimer(signal.ITIMER_REAL, 0)
            Watchdog._stop_ticking()
            for signum in self._signals:
                if signal.getsignal(signum) is _deadline_expired:
                    signal.signal(signum, signal.SIG_DFL)
        self._installed = False

    def _limits_for(self, seconds: float) -> tuple[int, int]:
        """The tick of each timer (``ITIMER_REAL``, ``ITIMER_PROF``) that proves a call of
        deadline ``seconds`` (CPU time; ``blocked_wall_s`` on the wall clock) overran it:
        ceil(deadline / period) + 1."""
        real_s, prof_s = self._periods
        return (math.ceil(self.timing.blocked_wall_s / real_s - 1e-9) + 1,
                math.ceil(seconds / prof_s - 1e-9) + 1)

    def _tick(self) -> None:
        real_s, prof_s = self._periods
        signal.setitimer(signal.ITIMER_REAL, real_s, real_s)
        signal.setitimer(signal.ITIMER_PROF, prof_s, prof_s)
        _TIMERS.ticking = self._periods

    @staticmethod
    def _stop_ticking() -> None:
        if _TIMERS.ticking is not None:
            signal.setitimer(signal.ITIMER_REAL, 0)
            signal.setitimer(signal.ITIMER_PROF, 0)
            _TIMERS.ticking = None

    def _handled(self) -> bool:
        """Every signal this watchdog needs goes to the deadline handler (this watchdog's or
        another pipeline's in the process)."""
        # written out: asked at every driver call
        return _current_handler(signal.SIGALRM) is _deadline_expired and (
            not self.timing.cpu or _current_handler(signal.SIGPROF) is _deadline_expired)

    def _install(self) -> bool:
        """Take the signals when nobody handles them (and this is the main thread)."""
        if threading.current_thread() is not threading.main_thread() or any(
                signal.getsignal(signum) not in (signal.SIG_DFL, None, _deadline_expired)
                for signum in self._signals):
            return False
        for signum in self._signals:
            signal.signal(signum, _deadline_expired)
        self._installed = True
        return True


class _Timers:
    """The watchdog's process-wide state (the signal handler is process-wide)."""

    __slots__ = ("active", "cpu_ticks", "limits", "ticking", "wall_ticks")

    def __init__(self) -> None:
        self.active = False
        """A driver call is being timed."""
        self.ticking: tuple[float, float] | None = None
        """The periods (s) of the ticking ``ITIMER_REAL`` and ``ITIMER_PROF`` when they
        tick."""
        self.wall_ticks = 0
        """``ITIMER_REAL`` ticks since the timed call began."""
        self.cpu_ticks = 0
        """``ITIMER_PROF`` ticks since the timed call began."""
        self.limits: tuple[int, int] = (1, 1)
        """The ``ITIMER_REAL`` and ``ITIMER_PROF`` tick at which the timed call is cut
        off."""


_TIMERS = _Timers()


def _deadline_expired(signum: int, frame: FrameType | None) -> None:
    timers = _TIMERS
    if not timers.active:
        return  # a tick between calls
    if timers.ticking is not None:
        if signum == signal.SIGPROF:
            timers.cpu_ticks += 1
            if timers.cpu_ticks < timers.limits[1]:
                return
        else:
            timers.wall_ticks += 1
            if timers.wall_ticks < timers.limits[0]:
                return
    timers.active = False
    raise DriverDeadline


class ContainedSinks:
    """The run's sinks, each contained: one that raises is aborted (``abort()`` when it has
    one, else ``close()``), named, counted and left out of the rest of the run."""

    def __init__(self, sinks: Sequence[Sink], containment: Containment,
                 registry: Registry) -> None:
        self.containment = containment
        self.registry = registry
        self.active: list[Sink] = list(sinks)
        self.failed: list[Sink] = []

    def handle(self, event: Event) -> None:
        for sink in self.active:
            try:
                sink.handle(event)
            except Exception as exc:  # a sink's failure is its own (module docstring)
                self._failed(sink, event, exc)

    def _failed(self, sink: Sink, event: Event, exc: Exception) -> None:
        self.active = [s for s in self.active if s is not sink]
        self.failed.append(sink)
        name = sink_name(sink)
        faults = self.containment.record(f"sink {name!r}", sink_origin(sink, self.registry))
        faults.counts["exceptions"] += 1
        try:
            (getattr(sink, "abort", None) or sink.close)()
            ended = "aborted" if hasattr(sink, "abort") else "closed"
        except Exception as second:
            ended = f"not closed either ({describe_exception(second)})"
        faults.disable(f"after it raised {describe_exception(exc)} at "
                       f"t={event.t_ns / 1e9:.3f} s ({ended})", self.containment.warn)


def sink_name(sink: object) -> str:
    return str(getattr(sink, "name", "") or type(sink).__name__)


def sink_origin(sink: object, registry: Registry) -> str:
    """Where a sink's class comes from: the plugin that registered it, else its module (a
    sink the caller made itself)."""
    for registration in registry.sinks.entries.values():
        if registration.obj is type(sink):
            return plugin_origin(registration)
    return f"module {type(sink).__module__}"
