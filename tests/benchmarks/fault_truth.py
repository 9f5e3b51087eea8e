"""What the soak (soak.py) and the fault matrix (fault_matrix.py) share: the devices of a
bundled board and the faults each can have, one fault of each kind, and the checker that
judges every event of an emulated run against the simulation's truth (plain module; not
collected by pytest).

The checker counts, per run:

* **NaN**: valid samples or estimates with a non-finite value;
* **wrong valid**: valid samples farther from the truth than the chip's error model allows,
  each attributed to the faults in force at its time. A sample is compared with the truth
  at its time stamp and up to its latency before (the closest counts). Pressure and
  temperature (never calibrated) are compared with the truth plus the error model's own
  bias for this seed, within 6 sigma of noise and two resolution steps. Vectors (calibrated
  and rotated to the body frame) are compared with the truth within what the error model
  can do at all: constant and turn-on bias at 6 sigma, bias random walk over the run,
  temperature coefficient, scale and cross-axis error at 6 sigma, hard and soft iron,
  6 sigma noise and two resolution steps, per axis, times sqrt(3). A valid GNSS velocity
  more than VELOCITY_MARGIN_M_S off is wrong (positions are not checked: no truth in
  degrees);
* **in range by design**: a valid pressure that matches what a ``wrong_pressure`` fault made
  the world measure (truth plus its offset, within the same tolerance) is no driver's
  failure (in range and plausible: no sensor can tell) and is not counted wrong; it is
  recorded apart with whether the vario's innovation gate rejected it (the estimate at its
  time stamp says ``altitude_gated``) and the vario's climb-rate error in the 2 s before and
  after it. So is a pressure between the truth and the truth plus the offset in that
  fault's window: a chip's own filter (the BMP280's IIR) blends the wrong measurement into
  its next outputs;
* **held by a hung chip**: a valid sample of a chip under a ``frozen`` fault that is off
  the truth at its time stamp but within tolerance of the world at most the driver's
  stated detection time before it (``frozen_detection_outputs()`` output periods, where
  the driver states one: the BMP280, whose IIR filter settles on the hung word before its
  window can fill) is the stated cost of a hang, counted apart (``frozen_held``), not
  wrong; a driver that states none gets no such allowance;
* **out of order**: valid samples older than a valid sample their device already gave for
  the same quantity (and how many the pipeline flagged OUT_OF_ORDER);
* **unflagged wrong estimates**: an attitude or vertical estimate that is not finite (and
  not a ``RejectedEstimate``), or a climb rate more than CLIMB_MARGIN_M_S off the truth
  after SETTLE_S; ``RejectedEstimate`` events (refused or withheld) are counted apart;
* **tilt handed out**: every finite attitude estimate's tilt error against the truth (deg,
  heading-free), kept as its worst and the count more than TILT_MARGIN_DEG off after
  SETTLE_S, per estimator (a figure, not a failure: how good the attitudes are that an
  estimator hands out while it withholds others).
"""

from __future__ import annotations

import math
from collections import Counter, OrderedDict, deque
from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from imuhal.core.samples import (
    Quantity,
    Sample,
    SampleFlag,
    ScalarSample,
    VectorSample,
    VelocitySample,
)
from imuhal.emulation import faults, open_emulated
from imuhal.estimation.outputs import AttitudeEstimate, RejectedEstimate, VerticalEstimate
from imuhal.pipeline import Pipeline
from imuhal.plugins.manager import Registry
from imuhal.profile.faults import CHIP_FAULT_KINDS
from imuhal.profile.model import BoardProfile
from imuhal.sim.errors import (
    ScalarErrorSpec,
    SensorErrorModel,
    SensorErrorSpec,
    VectorErrorSpec,
)
from imuhal.sim.scenario import TruthState
from imuhal_filters.common.quat import tilt_error_deg

SIGMAS = 6.0
"""Gaussian error terms are allowed this many standard deviations."""
LATENCY_S = {Quantity.ACCEL: 0.008, Quantity.GYRO: 0.008, Quantity.MAG: 0.027,
             Quantity.PRESSURE: 0.045, Quantity.TEMPERATURE: 0.045}
"""How far before its time stamp a sample's measurement may lie, at least (two sample
periods at the seed board's rates: 250 Hz IMU, 75 Hz magnetometer, 50 Hz barometer with 9 ms
conversions); ``latency_of`` raises it for slower streams."""
VELOCITY_MARGIN_M_S = 2.0
"""A valid GNSS velocity further than this from the truth is wrong (issue 26 item 2)."""
CLIMB_MARGIN_M_S = 3.0
"""A vertical estimate's climb rate further than this from the truth is wrong..."""
SETTLE_S = 3.0
"""...after this long (the filters start from zero climb)."""
TILT_MARGIN_DEG = 10.0
"""An attitude estimate whose tilt is further than this from the truth is counted apart
(the flight benchmark's rc-flight target: tilt max below 10 deg)."""
KINDS = ("bus_errors", "os_error", "all_ones", "all_zeros", "corrupt_byte", "absent", "reset",
         "stuck_data_ready", "frozen", "corrupt_trim", "late_polls", "jitter", "host_stall",
         "wild_value", "wrong_pressure", "stale_navigation")
"""Every kind of imuhal.emulation.faults (FAULT_KINDS), in its order, but kinds added after
the matrix was first run go last (``stale_navigation``): the matrix groups consecutive kinds
in threes, and the published triples (``host_stall+wild_value+wrong_pressure``) stay the
same."""
WILD_CHANNELS = ("accel", "gyro", "mag", "pressure", "temperature")
"""The quantities a ``wild_value`` can replace."""
_WINDOW_KINDS: dict[str, Any] = {
    "all_ones": faults.AllOnes, "all_zeros": faults.AllZeros, "absent": faults.ChipAbsent,
    "stuck_data_ready": faults.StuckDataReady, "frozen": faults.FrozenData,
    "stale_navigation": faults.StaleNavigation}


# -- the devices of a board and their faults -------------------------------------------------

@dataclass
class Device:
    """What a fault plan needs to know of one device of a board."""

    name: str
    serial: bool
    chip_faults: frozenset[str]
    channels: tuple[str, ...]
    rate_hz: float
    full_scale: dict[str, float] = field(default_factory=dict)

    def wild_channels(self) -> list[str]:
        """The quantities of the device a ``wild_value`` can replace."""
        return [c for c in self.channels if c in WILD_CHANNELS]

    def can_have(self, kind: str) -> bool:
        """Whether the fault API offers ``kind`` on this device: chip kinds where its
        emulator models them, ``corrupt_byte`` on a serial line, ``wrong_pressure`` on a
        barometer, ``wild_value`` on a quantity a chip measures."""
        if kind in CHIP_FAULT_KINDS:
            return kind in self.chip_faults
        if kind == "corrupt_byte":
            return self.serial
        if kind == "wrong_pressure":
            return "pressure" in self.channels
        if kind == "wild_value":
            return bool(self.wild_channels())
        return True


def devices_of(profile: BoardProfile, registry: Registry) -> list[Device]:
    """Every enabled device, from one fault-free open of the board (rates and full scales
    as the drivers read them back)."""
    out = []
    with open_emulated(profile, registry, seed=1) as p:
        for name, dev in p.devices.items():
            cfg = profile.devices[name]
            bus = cfg.bus.split("/")[0]
            kind = profile.buses[bus].kind if bus in profile.buses else None
            emulator = registry.emulators.get(cfg.driver)
            channels = tuple(c.value for c in type(dev.driver).channels)
            rate = max((s.rate_hz for s in dev.streams), default=1.0)
            full = {c.value: fs for c, fs in dev.full_scale.items() if fs}
            out.append(Device(name, kind == "serial", emulator.chip_faults(), channels, rate,
                              full))
    return out


def make_fault(kind: str, dev: Device, start_s: float, end_s: float | None = None, *,
               rate: float = 0.01, index: int = 0) -> faults.FaultSpec | None:
    """One fault of ``kind`` on ``dev`` from ``start_s`` (None where the device cannot have
    it). Window kinds last to ``end_s``; ``bus_errors`` and ``os_error`` fail a transfer
    with probability ``rate``; ``host_stall`` stalls the host 20 ms at random, a fraction
    ``rate`` of the time; ``late_polls`` are 10 ms late, ``jitter`` up to 5 ms. One-offs
    vary with ``index``: ``corrupt_byte`` flips bit ``index % 8`` of byte ``index % 7``;
    ``wild_value`` is 1000 times the full scale on axis ``index % 3`` of the device's
    ``index``-th quantity (in turn); ``wrong_pressure`` is +300 Pa."""
    d = dev.name
    if not dev.can_have(kind):
        return None
    window: dict[str, Any] = {"device": d, "start_s": start_s, "end_s": end_s}
    if kind == "bus_errors":
        return faults.BusErrors(rate=rate, **window)
    if kind == "os_error":
        return faults.BusOSError(rate=rate, **window)
    if kind in _WINDOW_KINDS:
        return _WINDOW_KINDS[kind](**window)  # type: ignore[no-any-return]
    if kind == "late_polls":
        return faults.LatePolls(delay_s=0.01, **window)
    if kind == "jitter":
        return faults.TimingJitter(max_delay_s=0.005, **window)
    if kind == "host_stall":
        return faults.HostStall(stall_s=0.02, rate_hz=min(rate / 0.02, 100), **window)
    return _one_off(kind, dev, start_s, index)


def _one_off(kind: str, dev: Device, start_s: float, index: int) -> faults.FaultSpec | None:
    d = dev.name
    if kind == "reset":
        return faults.ChipReset(device=d, start_s=start_s)
    if kind == "corrupt_trim":
        return faults.CorruptTrim(device=d, start_s=start_s)
    if kind == "corrupt_byte":
        return faults.CorruptByte(device=d, start_s=start_s, byte=index % 7,
                                  mask=1 << (index % 8))
    if kind == "wrong_pressure":
        return faults.WrongPressure(device=d, start_s=start_s, offset_pa=300.0)
    wild = dev.wild_channels()
    channel = wild[index % len(wild)]
    return faults.WildValue(device=d, start_s=start_s, channel=channel,  # type: ignore[arg-type]
                            axis=index % 3, value=1000.0 * dev.full_scale.get(channel, 1e5))


def fault_window(spec: faults.FaultSpec, duration_s: float) -> tuple[float, float]:
    """When a fault can affect samples: its window, plus 1 s of aftermath."""
    hold = getattr(spec, "hold_s", 0.0)
    end = spec.end_s if spec.end_s is not None else (
        spec.start_s + hold if hold else (duration_s if not spec.instantaneous
                                          else spec.start_s))
    return spec.start_s, end + 1.0


def latency_of(pipeline: Pipeline) -> dict[Quantity, float]:
    """Per quantity: two periods of the slowest stream carrying it plus its declared
    latency, never below LATENCY_S."""
    out = dict(LATENCY_S)
    for streams in pipeline.streams.values():
        for spec in streams:
            channel = spec.quantity
            if channel in out:
                out[channel] = max(out[channel], 2.0 / spec.rate_hz + spec.latency_s)
    return out


# -- tolerances from the chips' error models ------------------------------------------------

def _vector_tolerance(spec: VectorErrorSpec | None, resolution: float, duration_s: float,
                      magnitude: float, delta_t_degc: float) -> float:
    """Largest per-axis error the error model allows for a true magnitude ``magnitude``."""
    if spec is None:
        return 2 * resolution
    s = SIGMAS
    bias = max(map(abs, spec.bias)) + s * spec.bias_std \
        + s * spec.bias_random_walk * math.sqrt(duration_s) \
        + max(map(abs, spec.bias_temp_coeff)) * delta_t_degc
    cross = max(abs(c) for row in spec.cross_axis for c in row)
    gain = max(map(abs, spec.scale_factor_error)) + s * spec.scale_factor_std \
        + 2 * (cross + s * spec.cross_axis_std)
    bandwidth = spec.bandwidth_hz or 500.0
    noise = math.hypot(spec.noise_std, spec.noise_density * math.sqrt(bandwidth))
    extra = 0.0
    hard_iron = getattr(spec, "hard_iron_ut", None)
    if hard_iron is not None:
        soft = np.asarray(spec.soft_iron)
        extra = float(np.linalg.norm(hard_iron)) + float(np.abs(soft - np.eye(3)).sum(axis=1)
                                                         .max()) * magnitude
    return bias + gain * magnitude + s * noise + 2 * resolution + extra


def _scalar_tolerance(spec: ScalarErrorSpec | None, resolution: float, duration_s: float,
                      delta_t_degc: float) -> float:
    if spec is None:
        return 2 * resolution
    s = SIGMAS
    return abs(spec.bias) + s * spec.bias_std + abs(spec.drift_per_hour) * duration_s / 3600 \
        + s * spec.random_walk * math.sqrt(duration_s) + abs(spec.temp_coeff) * delta_t_degc \
        + s * spec.noise_std + 2 * resolution


_TRUE_VECTOR = {Quantity.ACCEL: "specific_force_body_m_s2",
                Quantity.GYRO: "angular_rate_body_rad_s",
                Quantity.MAG: "magnetic_field_body_ut"}


@dataclass
class Report:
    """What the checker found in one run (the soak adds its own figures)."""

    duration_s: float
    seed: int
    board: str = ""
    crashes: list[str] = field(default_factory=list)
    nan: Counter[str] = field(default_factory=Counter)
    checked: Counter[str] = field(default_factory=Counter)
    wrong_valid: Counter[str] = field(default_factory=Counter)
    wrong_by_fault: Counter[str] = field(default_factory=Counter)
    """Wrong valid samples by quantity and the faults in force (and their aftermath)."""
    first_wrong_s: dict[str, float] = field(default_factory=dict)
    """The first time (simulated s) of each entry of ``wrong_by_fault`` and
    ``wrong_estimates_by_fault``, to find it again."""
    worst: dict[str, float] = field(default_factory=dict)
    out_of_order: Counter[str] = field(default_factory=Counter)
    flagged_out_of_order: int = 0
    flagged_spans: dict[str, tuple[int, int, int]] = field(default_factory=dict)
    """Per device, quantity and flag: first and last time stamp (ns), count."""
    by_design: list[dict[str, Any]] = field(default_factory=list)
    """Valid samples that are wrong because the world was (``wrong_pressure``: in range and
    plausible, no driver can tell): where each was, and what the vario made of it."""
    frozen_held: int = 0
    """Valid samples of a hung chip within its driver's stated detection time (the world
    of when it hung), counted apart from the wrong ones."""
    by_design_blended: int = 0
    """Valid pressures between the truth and a ``wrong_pressure``'s (a chip's filter)."""
    wrong_estimates: Counter[str] = field(default_factory=Counter)
    """Unflagged wrong estimates, by estimator and what was wrong."""
    wrong_estimates_by_fault: Counter[str] = field(default_factory=Counter)
    rejected_estimates: Counter[str] = field(default_factory=Counter)
    """RejectedEstimate events (refused or withheld), by estimator."""
    attitudes: Counter[str] = field(default_factory=Counter)
    """Finite attitude estimates handed out after SETTLE_S, by estimator."""
    tilt_over: Counter[str] = field(default_factory=Counter)
    """Of those, the ones more than TILT_MARGIN_DEG off the true tilt, by estimator."""
    worst_tilt_deg: dict[str, float] = field(default_factory=dict)
    """The worst tilt error (deg) of those, by estimator."""
    delivered: dict[str, tuple[int, float]] = field(default_factory=dict)
    """Per device and quantity: (valid samples, samples the stream's rate promises)."""
    startups: dict[str, tuple[int, int]] = field(default_factory=dict)
    rss_mb: dict[str, float] = field(default_factory=dict)
    simulated_s: float = 0.0
    """How far the run got (simulated seconds)."""
    summary: str = ""
    fault_log: list[str] = field(default_factory=list)
    injected: dict[str, dict[str, int]] = field(default_factory=dict)
    wall_s: float = 0.0


class Checker:
    """Judges every event of the run against the truth."""

    def __init__(self, pipeline: Pipeline, plan: Sequence[faults.FaultSpec], report: Report,
                 models: dict[str, SensorErrorModel], *,
                 latency_s: dict[Quantity, float] | None = None, margin: float = 1.0) -> None:
        """``latency_s``: per quantity, how far before its time stamp a measurement may lie
        (default ``latency_of(pipeline)``); ``margin`` multiplies every tolerance."""
        self.p = pipeline
        self.latency_s = latency_of(pipeline) if latency_s is None else latency_s
        self.margin = margin
        self.models = models
        self.report = report
        self.scenario = pipeline.board.scenario  # type: ignore[attr-defined]
        self.windows = [(f"{s.kind}:{s.device}", *fault_window(s, report.duration_s))
                        for s in plan if not isinstance(s, faults.BusErrors)]
        self.specs: dict[str, SensorErrorSpec | None] = {
            name: type(emu).error_spec
            for name, emu in pipeline.board.emulators.items()}  # type: ignore[attr-defined]
        self.wrong_world = [(s.device, s.offset_pa, *fault_window(s, report.duration_s))
                            for s in plan if isinstance(s, faults.WrongPressure)]
        self.frozen = [(s.device, s.start_s, s.end_s if s.end_s is not None
                        else report.duration_s) for s in plan
                       if isinstance(s, faults.FrozenData)]
        self._recent_climb: deque[tuple[int, float]] = deque(maxlen=512)
        """(t_ns, |climb - true climb|) of the last vario estimates."""
        self.last: dict[tuple[str, Quantity], int] = {}
        self._truth: OrderedDict[int, TruthState] = OrderedDict()
        self._resolution: dict[tuple[str, Quantity], float] = {}

    def truth(self, t_ns: int) -> TruthState:
        state = self._truth.get(t_ns)
        if state is None:
            state = self.scenario.truth(max(t_ns, 0) / 1e9)
            self._truth[t_ns] = state
            if len(self._truth) > 256:
                self._truth.popitem(last=False)
        return state

    def resolution(self, device: str, channel: Quantity) -> float:
        key = (device, channel)
        if key not in self._resolution:
            try:
                self._resolution[key] = self.p.board.emulators[device].resolution(channel)  # type: ignore[attr-defined]
            except (NotImplementedError, ValueError):
                self._resolution[key] = 0.0
        return self._resolution[key]

    def faults_at(self, t_ns: int) -> str:
        """The faults in force (with their aftermath) at ``t_ns``, for attribution."""
        t_s = t_ns / 1e9
        return ", ".join(name for name, a, b in self.windows if a <= t_s <= b) or "no fault"

    def handle(self, event: object) -> None:
        if isinstance(event, VelocitySample):
            self._velocity(event)
        elif isinstance(event, Sample):
            if event.channel in self.latency_s:  # GNSS position: no truth in degrees
                self._sample(event)
        elif isinstance(event, AttitudeEstimate):
            if not all(map(math.isfinite, event.q_body_to_ned)):
                self.report.nan[f"{event.source} attitude"] += 1
                self._wrong_estimate(event, "attitude not finite")
            elif event.t_ns / 1e9 > SETTLE_S:
                self._tilt(event)
        elif isinstance(event, VerticalEstimate):
            self._vertical(event)
        elif isinstance(event, RejectedEstimate):
            self.report.rejected_estimates[event.source] += 1

    def _attribute(self, counts: Counter[str], what: str, t_ns: int) -> None:
        """Count ``what`` under the faults in force at ``t_ns``."""
        key = f"{what} during {self.faults_at(t_ns)}"
        counts[key] += 1
        self.report.first_wrong_s.setdefault(key, t_ns / 1e9)

    def _wrong_estimate(self, e: AttitudeEstimate | VerticalEstimate, what: str) -> None:
        self.report.wrong_estimates[f"{e.source} {what}"] += 1
        self._attribute(self.report.wrong_estimates_by_fault, f"{e.source} {what}", e.t_ns)

    def _tilt(self, e: AttitudeEstimate) -> None:
        """Count a finite attitude handed out, its worst tilt error, and whether it is
        more than TILT_MARGIN_DEG off."""
        error = tilt_error_deg(e.q_body_to_ned, tuple(self.truth(e.t_ns).q_body_to_ned))
        report = self.report
        report.attitudes[e.source] += 1
        report.worst_tilt_deg[e.source] = max(report.worst_tilt_deg.get(e.source, 0.0), error)
        if error > TILT_MARGIN_DEG:
            report.tilt_over[e.source] += 1

    def _vertical(self, e: VerticalEstimate) -> None:
        if not (math.isfinite(e.altitude_m) and math.isfinite(e.climb_m_s)):
            self.report.nan[f"{e.source} vertical"] += 1
            self._wrong_estimate(e, "vertical not finite")
            return
        if e.t_ns / 1e9 > SETTLE_S and \
                abs(e.climb_m_s - self.truth(e.t_ns).climb_m_s) > CLIMB_MARGIN_M_S:
            self._wrong_estimate(e, "climb off")
        if "altitude_gated" in e.diagnostics:
            self._vario(e)

    def _vario(self, e: VerticalEstimate) -> None:
        """A gated vario's estimate near a by-design wrong pressure: was that pressure
        gated out, and how far did the climb rate stray from the truth before and after?"""
        climb_error = abs(e.climb_m_s - self.truth(e.t_ns).climb_m_s)
        self._recent_climb.append((e.t_ns, climb_error))
        for entry in self.report.by_design:
            if entry["t_ns"] == e.t_ns:
                entry["gated"] = bool(e.diagnostics["altitude_gated"])
            if 0 <= e.t_ns - entry["t_ns"] <= 2_000_000_000:
                entry["climb_error_after"] = max(entry.get("climb_error_after", 0.0),
                                                 climb_error)

    def _velocity(self, s: VelocitySample) -> None:
        if not s.valid:
            return
        errors = [math.dist(s.velocity_ned_m_s, self.truth(s.t_ns - lag).velocity_ned_m_s)
                  for lag in (0, 100_000_000, 200_000_000)]
        key = f"{s.device} velocity"
        self.report.checked[key] += 1
        if min(errors) > VELOCITY_MARGIN_M_S:
            self.report.wrong_valid[key] += 1
            self._attribute(self.report.wrong_by_fault, key, s.t_ns)

    def _sample(self, s: Sample) -> None:
        if SampleFlag.OUT_OF_ORDER in s.flags:
            self.report.flagged_out_of_order += 1
        if not s.valid:
            for flag in SampleFlag:
                if flag and flag in s.flags:
                    key = f"{s.device} {s.channel.value} {flag.name}"
                    first, last, n = self.report.flagged_spans.get(key, (s.t_ns, s.t_ns, 0))
                    self.report.flagged_spans[key] = (first, s.t_ns, n + 1)
            return
        key = f"{s.device} {s.channel.value}"
        values = s.vector if isinstance(s, VectorSample) else (
            (s.scalar,) if isinstance(s, ScalarSample) else ())
        if not all(map(math.isfinite, values)):
            self.report.nan[key] += 1
            return
        last = self.last.get((s.device, s.channel))
        if last is not None and s.t_ns < last:
            self.report.out_of_order[key] += 1
        self.last[(s.device, s.channel)] = s.t_ns
        error, tolerance = self._error(s, values)
        if error > tolerance and (self._wrong_by_design(s, values)
                                  or self._held_by_hung_chip(s, values, tolerance)):
            return
        self.report.checked[key] += 1
        ratio = error / tolerance if tolerance > 0 else math.inf
        self.report.worst[key] = max(self.report.worst.get(key, 0.0), ratio)
        if error > tolerance:
            self.report.wrong_valid[key] += 1
            self._attribute(self.report.wrong_by_fault, key, s.t_ns)

    def _held_by_hung_chip(self, s: Sample, values: tuple[float, ...],
                           tolerance: float) -> bool:
        """A valid sample of a chip in a ``frozen`` window that matches the world of at most
        its driver's stated detection time before it (counted apart)."""
        t_s = s.t_ns / 1e9
        driver = self.p.devices[s.device].driver
        stated = getattr(driver, "frozen_detection_outputs", None)
        if stated is None or not any(d == s.device and a <= t_s <= b + self.latency_s[s.channel]
                                     for d, a, b in self.frozen):
            return False
        period_ns = max((spec.period_ns for spec in self.p.streams.get(s.device, ())
                         if spec.quantity is s.channel), default=0)
        if not period_ns:
            return False
        lag_ns = round(self.latency_s[s.channel] * 1e9)
        for k in range(1, stated() + 1):
            back = replace(s, t_ns=s.t_ns - k * period_ns)
            if self._error(back, values)[0] <= tolerance:
                self.report.frozen_held += 1
                return True
            if s.t_ns - k * period_ns < -lag_ns:
                break
        return False

    def _wrong_by_design(self, s: Sample, values: tuple[float, ...]) -> bool:
        """A pressure that matches what a ``wrong_pressure`` fault made the world measure
        (truth + offset, within the same tolerance): valid by design, recorded apart; or
        one between the truth and that, in the fault's window (a chip's filter blending
        the wrong measurement into its next outputs), counted apart."""
        if s.channel is not Quantity.PRESSURE:
            return False
        t_s = s.t_ns / 1e9
        for device, offset, start, end in self.wrong_world:
            if device != s.device or not start <= t_s <= end:
                continue
            error, tolerance = self._error(s, values, offset=offset)
            if error <= tolerance:
                before = [err for t, err in self._recent_climb
                          if s.t_ns - t <= 2_000_000_000]
                self.report.by_design.append({
                    "t_ns": s.t_ns, "quantity": f"{s.device} pressure",
                    "fault": f"wrong_pressure {offset:+g} Pa", "gated": None,
                    "climb_error_before": max(before, default=math.nan)})
                return True
            low, high = min(0.0, offset), max(0.0, offset)
            shifted = [self._error(s, values, offset=o) for o in (low, high)]
            if self._error(s, values, offset=(low + high) / 2)[0] <= \
                    (high - low) / 2 + max(tol for _, tol in shifted):
                self.report.by_design_blended += 1
                return True
        return False

    def _error(self, s: Sample, values: tuple[float, ...], offset: float = 0.0
               ) -> tuple[float, float]:
        """The sample's error against the truth (plus ``offset``, scalars) and the
        tolerance its chip's error model allows."""
        spec = self.specs.get(s.device)
        channel = s.channel
        lag_ns = round(self.latency_s[channel] * 1e9)
        times = (s.t_ns, s.t_ns - lag_ns // 2, s.t_ns - lag_ns)
        best = math.inf
        truth = self.truth(s.t_ns)
        delta_t = abs(truth.temperature_degc - 25.0) + 5.0
        resolution = self.resolution(s.device, channel)
        if channel in _TRUE_VECTOR:
            attr = _TRUE_VECTOR[channel]
            for t in times:
                true = getattr(self.truth(t), attr)
                best = min(best, math.dist(values, true))
            magnitude = float(np.linalg.norm(getattr(truth, attr)))
            sub = getattr(spec, channel.value) if spec is not None else None
            # per-axis tolerance, over three axes (the rotation to body mixes them)
            tol = math.sqrt(3) * _vector_tolerance(sub, resolution, self.report.duration_s,
                                                   magnitude, delta_t)
            return best, tol * self.margin
        # Scalars get no calibration, so the error model's own bias (the same seeded draw
        # the run used; constant for these chips) is known: only noise is left to allow.
        attr = "pressure_pa" if channel is Quantity.PRESSURE else "temperature_degc"
        sub = getattr(spec, channel.value) if spec is not None else None
        model = self.models.get(s.device)
        exact = sub is not None and model is not None and not sub.random_walk
        for t in times:
            state = self.truth(t)
            expected = getattr(state, attr) + offset
            if exact:
                assert model is not None
                expected += float(model.bias(channel.value, state.temperature_degc,  # type: ignore[arg-type]
                                             t / 1e9))
            best = min(best, abs(values[0] - expected))
        if exact:
            assert sub is not None
            return best, (SIGMAS * sub.noise_std + 2 * resolution + 1e-9) * self.margin
        return best, _scalar_tolerance(sub, resolution, self.report.duration_s,
                                       delta_t) * self.margin
