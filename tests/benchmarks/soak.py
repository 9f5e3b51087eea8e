"""Soak benchmark: the seed board under every fault, checked against the simulation's truth
(plain script; not collected by pytest).

Run:  .venv/bin/python tests/benchmarks/soak.py [--duration 3600] [--startups 40] [--seed 1]

The seed paraglider vario board (profiles/seed-paraglider-vario.yaml), every chip emulated at
register level with its datasheet error model, flies the ``thermal`` scenario (glides and
thermals repeated, so the altitude stays near launch however long the run) for
``--duration`` simulated seconds with 1 % random bus errors on every device on the SPI bus
(each transfer fails with probability 0.01) plus one instance of every fault kind of
imuhal.emulation.faults, spread over the run (the plan is printed). It reports:

* **crashes**: exceptions that escaped ``Pipeline.events`` (the run stops at the first);
* **NaN**: valid samples or estimates with a non-finite value;
* **wrong valid**: valid samples farther from the truth than the chip's error model allows,
  each attributed to the faults in force at its time. A sample is compared with the truth
  at its time stamp and up to two sample periods before (the closest counts). Pressure and
  temperature (never calibrated) are compared with the truth plus the error model's own
  bias for this seed, within 6 sigma of noise and two resolution steps. Vectors (calibrated
  and rotated to the body frame) are compared with the truth within what the error model
  can do at all: constant and turn-on bias at 6 sigma, bias random walk over the run,
  temperature coefficient, scale and cross-axis error at 6 sigma, hard and soft iron,
  6 sigma noise and two resolution steps, per axis, times sqrt(3);
* **in range by design**: a valid pressure that matches what the ``wrong_pressure`` fault
  made the world measure (truth plus its offset, within the same tolerance) is no driver's
  failure (in range and plausible: no sensor can tell) and is not counted wrong; it is
  reported apart with whether the vario's innovation gate rejected it (the estimate at its
  time stamp says ``altitude_gated``) and the vario's climb-rate error in the 2 s before and
  after it. The run fails if the gate let it through;
* **delivered**: valid samples of each quantity against what its configured rate promises
  over the run (what bus errors, recoveries and the faults cost);
* **out of order**: valid samples older than a valid sample their device already gave for
  the same quantity (and how many the pipeline flagged OUT_OF_ORDER);
* **start-up**: successful opens of every bundled board with 1 % bus errors on all its
  devices, over ``--startups`` seeds;
* **memory**: resident set size after the first minute and at the end.

Figures for docs/reliability.md come from a run of this script (``--markdown`` prints the
tables the page shows).
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
import time
import traceback
from collections import Counter, OrderedDict, deque
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from imuhal.core.samples import Quantity, Sample, SampleFlag, ScalarSample, VectorSample
from imuhal.emulation import error_models_for, open_emulated
from imuhal.emulation.faults import (
    AllOnes,
    AllZeros,
    BusErrors,
    BusOSError,
    ChipAbsent,
    ChipReset,
    CorruptTrim,
    FaultSpec,
    FrozenData,
    LatePolls,
    StuckDataReady,
    TimingJitter,
    WildValue,
    WrongPressure,
)
from imuhal.estimation.outputs import AttitudeEstimate, VerticalEstimate
from imuhal.pipeline import Pipeline
from imuhal.plugins.manager import Registry, load_registry
from imuhal.profile.bundled import bundled_profiles, default_profile_path
from imuhal.profile.loader import load_profile
from imuhal.sim.errors import (
    ScalarErrorSpec,
    SensorErrorModel,
    SensorErrorSpec,
    VectorErrorSpec,
)
from imuhal.sim.scenario import TruthState

SIGMAS = 6.0
"""Gaussian error terms are allowed this many standard deviations."""
LATENCY_S = {Quantity.ACCEL: 0.008, Quantity.GYRO: 0.008, Quantity.MAG: 0.027,
             Quantity.PRESSURE: 0.045, Quantity.TEMPERATURE: 0.045}
"""How far before its time stamp a sample's measurement may lie (two sample periods at the
seed board's rates: 250 Hz IMU, 75 Hz magnetometer, 50 Hz barometer with 9 ms
conversions)."""
NOMINAL_RATE_SETTINGS = {
    Quantity.PRESSURE: {"ms5611": "odr_hz", "bmp280": "odr_hz"},
    Quantity.GYRO: {"max21100": "gyro_odr_hz"},
    Quantity.ACCEL: {"max21100": "accel_odr_hz"},
    Quantity.MAG: {"hmc5883l": "odr_hz"},
}
"""Per quantity and driver: the setting that says how many samples a second it promises
(the delivered fraction is valid samples over that rate times the run)."""
ERROR_RATE = 0.01
SPI_DEVICES = ("imu", "baro")
"""The seed board's devices on the SPI bus; the magnetometer's transfers go through the
IMU's (its I2C master performs them), so the IMU's 1 % covers them."""


def flight_schedule(duration_s: float) -> tuple[tuple[float, float], ...]:
    """A thermal-scenario climb schedule that stays near launch altitude for any duration:
    60 s gliding at -1.1 m/s then 30 s climbing at 2.2 m/s, over and over (the scenario's
    default ends in an endless glide, which after an hour would leave the MS5611's range)."""
    schedule: list[tuple[float, float]] = [(0.0, 0.0)]
    t = 5.0
    while t < duration_s:
        schedule += [(t, -1.1), (t + 60.0, 2.2)]
        t += 90.0
    return tuple(schedule)


def fault_plan(duration_s: float) -> list[FaultSpec]:
    """1 % random bus errors plus one instance of every fault kind, spread over the run."""
    d = duration_s

    def at(fraction: float) -> float:
        return round(fraction * d, 3)

    plan: list[FaultSpec] = [BusErrors(device=dev, rate=ERROR_RATE) for dev in SPI_DEVICES]
    plan += [
        BusOSError(device="baro", start_s=at(0.05), end_s=at(0.05) + 0.2, rate=0.5),
        AllOnes(device="mag", start_s=at(0.10), end_s=at(0.10) + 0.5),
        AllZeros(device="baro", start_s=at(0.15), end_s=at(0.15) + 0.3),
        ChipAbsent(device="mag", start_s=at(0.20), end_s=at(0.20) + 2.0),
        ChipReset(device="imu", start_s=at(0.25)),
        StuckDataReady(device="imu", start_s=at(0.30), end_s=at(0.30) + 1.0),
        FrozenData(device="baro", start_s=at(0.35), end_s=at(0.35) + 5.0),
        LatePolls(device="imu", start_s=at(0.40), end_s=at(0.40) + 0.5, delay_s=0.05),
        TimingJitter(device="baro", start_s=at(0.45), end_s=at(0.45) + 10.0,
                     max_delay_s=0.005),
        WildValue(device="imu", channel="gyro", axis=2, value=100.0, start_s=at(0.50)),
        WrongPressure(device="baro", offset_pa=300.0, start_s=at(0.55)),
        # last: a corrupted PROM is permanent; the reset makes the driver read it again
        CorruptTrim(device="baro", start_s=at(0.90)),
        ChipReset(device="baro", start_s=at(0.90) + 0.5),
    ]
    return plan


def _window(spec: FaultSpec, duration_s: float) -> tuple[float, float]:
    """When a fault can affect samples: its window, plus 1 s of aftermath."""
    hold = getattr(spec, "hold_s", 0.0)
    end = spec.end_s if spec.end_s is not None else (
        spec.start_s + hold if hold else (duration_s if not spec.instantaneous
                                          else spec.start_s))
    return spec.start_s, end + 1.0


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
    duration_s: float
    seed: int
    crashes: list[str] = field(default_factory=list)
    nan: Counter[str] = field(default_factory=Counter)
    checked: Counter[str] = field(default_factory=Counter)
    wrong_valid: Counter[str] = field(default_factory=Counter)
    wrong_by_fault: Counter[str] = field(default_factory=Counter)
    worst: dict[str, float] = field(default_factory=dict)
    out_of_order: Counter[str] = field(default_factory=Counter)
    flagged_out_of_order: int = 0
    flagged_spans: dict[str, tuple[int, int, int]] = field(default_factory=dict)
    """Per device, quantity and flag: first and last time stamp (ns), count."""
    by_design: list[dict[str, Any]] = field(default_factory=list)
    """Valid samples that are wrong because the world was (``wrong_pressure``: in range and
    plausible, no driver can tell): where each was, and what the vario made of it."""
    delivered: dict[str, tuple[int, float]] = field(default_factory=dict)
    """Per quantity with a nominal rate: (valid samples, samples the rate promises)."""
    startups: dict[str, tuple[int, int]] = field(default_factory=dict)
    rss_mb: dict[str, float] = field(default_factory=dict)
    summary: str = ""
    fault_log: list[str] = field(default_factory=list)
    injected: dict[str, dict[str, int]] = field(default_factory=dict)
    wall_s: float = 0.0


class Checker:
    """Judges every event of the run against the truth."""

    def __init__(self, pipeline: Pipeline, plan: Sequence[FaultSpec], report: Report,
                 models: dict[str, SensorErrorModel], *,
                 latency_s: dict[Quantity, float] | None = None, margin: float = 1.0) -> None:
        """``latency_s``: per quantity, how far before its time stamp a measurement may lie
        (default LATENCY_S, the seed board's); ``margin`` multiplies every tolerance."""
        self.p = pipeline
        self.latency_s = LATENCY_S if latency_s is None else latency_s
        self.margin = margin
        self.models = models
        self.report = report
        self.scenario = pipeline.board.scenario  # type: ignore[attr-defined]
        self.windows = [(f"{s.kind}:{s.device}", *_window(s, report.duration_s)) for s in plan
                        if not isinstance(s, BusErrors)]
        self.specs: dict[str, SensorErrorSpec | None] = {
            name: type(emu).error_spec
            for name, emu in pipeline.board.emulators.items()}  # type: ignore[attr-defined]
        self.wrong_world = [(s.device, s.offset_pa, *_window(s, report.duration_s))
                            for s in plan if isinstance(s, WrongPressure)]
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

    def handle(self, event: object) -> None:
        if isinstance(event, Sample):
            self._sample(event)
        elif isinstance(event, AttitudeEstimate):
            if not all(map(math.isfinite, event.q_body_to_ned)):
                self.report.nan[f"{event.source} attitude"] += 1
        elif isinstance(event, VerticalEstimate):
            if not (math.isfinite(event.altitude_m) and math.isfinite(event.climb_m_s)):
                self.report.nan[f"{event.source} vertical"] += 1
            elif "altitude_gated" in event.diagnostics:
                self._vario(event)

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
        if error > tolerance and self._wrong_by_design(s, values):
            return
        self.report.checked[key] += 1
        ratio = error / tolerance if tolerance > 0 else math.inf
        self.report.worst[key] = max(self.report.worst.get(key, 0.0), ratio)
        if error > tolerance:
            self.report.wrong_valid[key] += 1
            t_s = s.t_ns / 1e9
            active = [name for name, a, b in self.windows if a <= t_s <= b]
            self.report.wrong_by_fault[f"{key} during {', '.join(active) or 'no fault'}"] += 1

    def _wrong_by_design(self, s: Sample, values: tuple[float, ...]) -> bool:
        """A pressure that matches what a ``wrong_pressure`` fault made the world measure
        (truth + offset, within the same tolerance): valid by design, recorded apart."""
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


def rss_mb() -> float:
    with open("/proc/self/statm") as f:
        pages = int(f.read().split()[1])
    return pages * os.sysconf("SC_PAGE_SIZE") / 1e6


def startup_trials(registry: Registry, attempts: int) -> dict[str, tuple[int, int]]:
    """Per bundled board: (successful opens, attempts) with 1 % bus errors on every device."""
    out = {}
    for board, path in sorted(bundled_profiles().items()):
        profile = load_profile(path, registry)
        devices = [n for n, d in profile.devices.items() if d.enabled]
        ok = 0
        for seed in range(attempts):
            faults = [BusErrors(device=d, rate=ERROR_RATE) for d in devices]
            try:
                with open_emulated(profile, registry, seed=seed, faults=faults) as p:
                    ok += all(d.present for d in p.devices.values())
            except Exception:
                pass
        out[board] = (ok, attempts)
    return out


def soak(duration_s: float, seed: int, startups: int, progress: bool = True) -> Report:
    registry = load_registry()
    report = Report(duration_s=duration_s, seed=seed)
    report.startups = startup_trials(registry, startups)
    profile = load_profile(default_profile_path(), registry)
    plan = fault_plan(duration_s)
    wall0 = time.perf_counter()
    report.rss_mb["start"] = rss_mb()
    try:
        pipeline = open_emulated(profile, registry, seed=seed, faults=plan,
                                 scenario_params={"schedule": flight_schedule(duration_s)})
    except Exception:
        report.crashes.append(traceback.format_exc())
        return report
    checker = Checker(pipeline, plan, report, error_models_for(profile, registry, seed))
    step = min(60.0, duration_s)
    done = 0.0
    try:
        while done < duration_s - 1e-9:
            chunk = min(step, duration_s - done)
            for event in pipeline.events(chunk):
                checker.handle(event)
            done += chunk
            if done == step:
                report.rss_mb["after 1 min"] = rss_mb()
            if progress:
                print(f"  {done:7.0f} s simulated, {time.perf_counter() - wall0:6.0f} s wall, "
                      f"RSS {rss_mb():6.1f} MB, wrong valid {sum(report.wrong_valid.values())}",
                      file=sys.stderr, flush=True)
    except Exception:
        report.crashes.append(traceback.format_exc())
    report.rss_mb["end"] = rss_mb()
    report.wall_s = time.perf_counter() - wall0
    for name, dev in pipeline.devices.items():
        for channel, setting in NOMINAL_RATE_SETTINGS.items():
            rate = getattr(dev.driver.settings, setting.get(dev.driver.name, ""), None)
            key = f"{name} {channel.value}"
            if rate and key in report.checked:
                report.delivered[key] = (report.checked[key], float(rate) * done)
    summary = pipeline.summary(simulated_s=done, wall_s=report.wall_s)
    report.summary = summary.describe()
    report.flagged = summary.flagged  # type: ignore[attr-defined]
    report.fault_log = list(pipeline.board.faults.log.events)  # type: ignore[attr-defined]
    report.injected = pipeline.board.faults.log.injected  # type: ignore[attr-defined]
    pipeline.close()
    return report


def markdown(report: Report) -> str:
    growth = report.rss_mb.get("end", 0.0) - report.rss_mb.get("after 1 min", 0.0)
    checked = sum(report.checked.values())
    lines = [
        f"Seed board, `thermal`, {report.duration_s:g} s simulated, seed {report.seed}, "
        f"{report.wall_s:.0f} s wall.",
        "",
        "| measure | result | target |",
        "|---|---|---|",
        f"| crashes | {len(report.crashes)} | 0 |",
        f"| NaN in valid samples or estimates | {sum(report.nan.values())} | 0 |",
        f"| valid samples wrong against the truth | {sum(report.wrong_valid.values())} of "
        f"{checked} | 0 |",
        f"| valid samples out of time order | {sum(report.out_of_order.values())} "
        f"({report.flagged_out_of_order} flagged OUT_OF_ORDER) | 0 |",
        f"| RSS growth after the first minute | {growth:.1f} MB "
        f"({report.rss_mb.get('after 1 min', 0):.0f} -> {report.rss_mb.get('end', 0):.0f} MB)"
        f" | < 10 MB |",
    ]
    for entry in report.by_design:
        gated = {True: "yes", False: "NO", None: "no estimate"}[entry["gated"]]
        lines.append(
            f"| in range by design ({entry['fault']}, {entry['quantity']} at "
            f"{entry['t_ns'] / 1e9:.2f} s): rejected by the vario's gate | {gated}; climb "
            f"error in the 2 s after {entry.get('climb_error_after', math.nan):.2f} m/s "
            f"(before {entry.get('climb_error_before', math.nan):.2f}) | yes |")
    for board, (ok, n) in report.startups.items():
        lines.append(f"| start-ups with 1 % bus errors, {board} | {ok}/{n} | {n}/{n} |")
    if report.wrong_by_fault:
        lines += ["", "Wrong valid samples by quantity and the faults in force:", "",
                  "| samples | count |", "|---|---|"]
        lines += [f"| {k} | {v} |" for k, v in sorted(report.wrong_by_fault.items())]
    lines += ["", "Flagged samples, by quantity and flag (first and last time):", "",
              "| samples | flag | count | first | last |", "|---|---|---|---|---|"]
    for key, (first, last, n) in sorted(report.flagged_spans.items()):
        what, flag = key.rsplit(" ", 1)
        lines.append(f"| {what} | {flag} | {n} | {first / 1e9:.1f} s | {last / 1e9:.1f} s |")
    if report.delivered:
        lines += ["", "Valid samples delivered against the configured rate (bus errors, "
                  "recoveries and the fault windows cost the rest):", "",
                  "| quantity | valid | promised | delivered |", "|---|---|---|---|"]
        lines += [f"| {k} | {n} | {promised:.0f} | {100 * n / promised:.1f} % |"
                  for k, (n, promised) in sorted(report.delivered.items())]
    lines += ["", "Worst error / tolerance among valid samples, per quantity:", "",
              "| quantity | checked | worst ratio |", "|---|---|---|"]
    lines += [f"| {k} | {report.checked[k]} | {report.worst[k]:.2f} |"
              for k in sorted(report.checked)]
    return "\n".join(lines)


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--duration", type=float, default=600.0, help="simulated seconds")
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--startups", type=int, default=40, help="start-up attempts per board")
    parser.add_argument("--json", metavar="FILE", help="also write the report as JSON")
    parser.add_argument("--quiet", action="store_true", help="no progress lines")
    args = parser.parse_args(argv)
    if not (math.isfinite(args.duration) and args.duration >= 60):
        parser.error("--duration must be at least 60 simulated seconds")
    print("fault plan:", file=sys.stderr)
    for spec in fault_plan(args.duration):
        print(f"  {spec!r}", file=sys.stderr)
    report = soak(args.duration, args.seed, args.startups, progress=not args.quiet)
    print(markdown(report))
    print("\nRun summary:\n\n```\n" + report.summary + "\n```")
    print("\nFault log:\n\n```\n" + "\n".join(report.fault_log) + "\n```")
    for crash in report.crashes:
        print("\nCRASH:\n" + crash, file=sys.stderr)
    if args.json:
        data: dict[str, Any] = {k: v for k, v in vars(report).items()}
        with open(args.json, "w", encoding="utf-8") as f:
            json.dump(data, f, indent=1, default=str)
    bad = (report.crashes or sum(report.nan.values()) or sum(report.out_of_order.values())
           or sum(report.wrong_valid.values())
           or any(entry["gated"] is not True for entry in report.by_design))
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
