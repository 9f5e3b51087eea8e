"""What the page receives: the live state as one JSON-ready dict, built at the display rate.

:class:`Snapshotter` runs on the publisher thread (never on the pipeline's). Each call copies
the :class:`~imuhal.live.sink.LiveSink`, reads the pipeline's counters (plain integers and a
list, safe to read while the pipeline runs) and the emulated truth if there is one, and keeps
a short history of its own copies to derive rates (samples per second of pipeline time) and
the bring-up evidence (the body rotation each sensor saw in the last seconds).

Units are in every key: SI at the boundary (m/s^2, rad/s, uT, Pa, degC, m, m/s), angles in
degrees for display (roll right +, pitch nose up +, heading clockwise from north), times in
seconds of pipeline time (``t_s``). Vectors are in the body frame (NED: x forward, y right,
z down).
"""

from __future__ import annotations

import math
import time
from collections import deque
from dataclasses import dataclass
from typing import Any, Protocol

from imuhal.core.samples import Quantity, Sample, ScalarSample, VectorSample
from imuhal.live.mounts import MOTIONS, Evidence, judge, mean_vector, rotation_between
from imuhal.live.sink import Copy, LiveSink
from imuhal.pipeline import Pipeline

WINDOW_S = 2.0
"""The bring-up checks and the achieved rates look at the last this many seconds."""
ENDS_S = 0.3
"""Accelerometer and magnetometer vectors are averaged over this long at each end of the
window (s)."""
STALE_PERIODS = 5.0
"""A device is stale when it has produced nothing for this many of its periods..."""
STALE_MIN_S = 0.5
"""... or this long (s), whichever is longer, of pipeline time."""
RATE_LOW = 0.8
"""A device achieving less than this fraction of its configured rate is marked faulty."""
BRINGUP_EVERY = 4
"""The bring-up evidence is rebuilt every this many snapshots (5 Hz at the default 20 Hz):
plenty for motions that last a second, and it is half of a snapshot's cost."""
FLAGGED_FAULTY = 0.05
"""More than this fraction of a device's samples flagged in the window marks it faulty (a
chip that flags the odd late sample is not)."""


class Truth(Protocol):
    """The simulated truth of an emulated run at one instant (imuhal.sim.scenario.TruthState
    has these)."""

    @property
    def t_s(self) -> float: ...

    @property
    def euler_deg(self) -> tuple[float, float, float]: ...

    @property
    def altitude_m(self) -> float: ...

    @property
    def climb_m_s(self) -> float: ...


class _Named(Protocol):
    @property
    def name(self) -> str: ...


class TruthSource(Protocol):
    """Where the truth of an emulated run comes from: its scenario (named on the page) and
    the truth at any time of the run. An ``imuhal.emulation.EmulatedBoard`` is one; the
    live view is handed it by whoever opened the board and never asks a board what it is."""

    @property
    def scenario(self) -> _Named: ...

    def truth_at(self, t_ns: int) -> Truth: ...


def configured_rates_hz(pipeline: Pipeline, device: str) -> dict[str, float]:
    """The output rate of each stream of ``device`` as its chip reports it (the stream specs
    read back at its last configuration, imuhal.core.streams), by quantity name; empty for
    a device not (yet) configured."""
    dev = pipeline.devices.get(device)
    if dev is None:
        return {}
    return {spec.quantity.name: spec.rate_hz for spec in dev.streams}


@dataclass
class _Past:
    t_ns: int
    counts: dict[str, dict[Quantity, int]]
    rotation: dict[str, tuple[float, float, float]]
    vectors: dict[tuple[str, Quantity], tuple[float, float, float]]
    faults: dict[str, int]
    flagged: dict[str, int]


class Snapshotter:
    """Builds successive snapshots of one run (keep one per live view)."""

    def __init__(self, sink: LiveSink, pipeline: Pipeline | None = None, *,
                 truth: TruthSource | None = None) -> None:
        """``truth``: an emulated run's truth, shown at the time of the latest event the
        ``sink`` received (None: real hardware, no truth)."""
        self.sink = sink
        self.pipeline = pipeline
        self.truth = truth
        self.scenario = truth.scenario.name if truth is not None else None
        self.seq = 0
        self._past: deque[_Past] = deque()
        self._drivers: dict[str, str] = {}
        self._bringup_state: dict[str, Any] | None = None
        self._last_events = 0
        self._last_change_wall = 0.0
        self._ended_summary: list[str] | None = None
        if pipeline is not None:
            for name, dev in pipeline.devices.items():
                drv = dev.driver
                self._drivers[name] = drv.name

    def _summary(self, copy: Copy) -> list[str] | None:
        """The run's summary (the lines ``imuhal run`` prints) once it has ended; None while
        it runs. Taken once per end (the pipeline is idle by then); the wall time is the
        view's, from the first event to the end."""
        if not copy.closed or self.pipeline is None:
            self._ended_summary = None
            return None
        if self._ended_summary is None:
            wall_s = 0.0 if copy.first_wall_s is None or copy.closed_wall_s is None else \
                copy.closed_wall_s - copy.first_wall_s
            self._ended_summary = self.pipeline.summary(
                wall_s=wall_s, simulated_s=self.pipeline.span_s).describe().splitlines()
        return self._ended_summary

    def snapshot(self) -> dict[str, Any]:
        """The state now, as the page receives it (one SSE message, JSON)."""
        copy = self.sink.copy()
        self.seq += 1
        now_wall = time.monotonic()
        out: dict[str, Any] = {
            "seq": self.seq,
            "t_s": None if copy.t_ns is None else copy.t_ns / 1e9,
            "age_s": self._age_s(copy.events, now_wall),
            "events": copy.events,
            "ended": copy.closed,
            "board": {
                "profile": self.pipeline.profile.name if self.pipeline is not None else None,
                "scenario": self.scenario,
                "emulated": self.truth is not None,
            },
            # In the profile's order: the page offers the first one by default.
            "attitude": {name: _attitude(copy.attitudes[name])
                         for name in self._ordered(copy.attitudes)},
            "vertical": {name: {"t_s": v.t_ns / 1e9, "altitude_m": v.altitude_m,
                                "climb_m_s": v.climb_m_s}
                         for name, v in ((n, copy.verticals[n])
                                         for n in self._ordered(copy.verticals))},
            "sensors": {name: _sensors(d.latest_valid, d.latest)
                        for name, d in sorted(copy.devices.items())},
            "truth": None,
            "warnings": list(self.pipeline.warnings) if self.pipeline is not None else [],
            "summary": self._summary(copy),
        }
        truth = self.truth.truth_at(copy.t_ns) \
            if self.truth is not None and copy.t_ns is not None else None
        if truth is not None:
            roll, pitch, yaw = truth.euler_deg
            out["truth"] = {"t_s": float(truth.t_s), "roll_deg": roll, "pitch_deg": pitch,
                            "heading_deg": yaw % 360.0, "altitude_m": truth.altitude_m,
                            "climb_m_s": truth.climb_m_s}
        past = self._remember(copy)
        out["health"] = self._health(copy, past)
        if self._bringup_state is None or self.seq % BRINGUP_EVERY == 0:
            self._bringup_state = self._bringup(copy, past)
        out["bringup"] = self._bringup_state
        return out

    def _age_s(self, events: int, now_wall: float) -> float | None:
        """Wall seconds since the pipeline's last event, as seen by successive snapshots
        (the sink itself reads no clock: that would cost every event)."""
        if events == 0:
            return None
        if events != self._last_events:
            self._last_events = events
            self._last_change_wall = now_wall
        return now_wall - self._last_change_wall

    def _ordered(self, names: dict[str, Any]) -> list[str]:
        """``names`` in the profile's estimator order (unknown ones last, sorted)."""
        order = ([e.name for e in self.pipeline.estimators]
                 if self.pipeline is not None else [])
        known = [n for n in order if n in names]
        return known + sorted(n for n in names if n not in order)

    # -- history ------------------------------------------------------------------------

    def _faults(self, name: str) -> int:
        """Bus errors plus device errors of ``name`` so far (0 without a pipeline)."""
        if self.pipeline is None or name not in self.pipeline.devices:
            return 0
        dev = self.pipeline.devices[name]
        return dev.bus_errors + dev.device_errors

    def _remember(self, copy: Copy) -> _Past | None:
        """Store this copy's essentials; return the oldest one within the window."""
        if copy.t_ns is None:
            return None
        if self._past and copy.t_ns < self._past[-1].t_ns:
            self._past.clear()  # a new run on the same sink: start over
        vectors = {}
        for name, d in copy.devices.items():
            for channel in (Quantity.ACCEL, Quantity.MAG):
                s = d.latest_valid.get(channel)
                if isinstance(s, VectorSample):
                    vectors[(name, channel)] = s.vector
        self._past.append(_Past(
            t_ns=copy.t_ns,
            counts={n: dict(d.counts) for n, d in copy.devices.items()},
            rotation={n: (d.rotation_rad[0], d.rotation_rad[1], d.rotation_rad[2])
                      for n, d in copy.devices.items() if d.last_gyro_ns is not None},
            vectors=vectors,
            faults={n: self._faults(n) for n in copy.devices},
            flagged={n: sum(d.flagged.values()) for n, d in copy.devices.items()}))
        while copy.t_ns - self._past[0].t_ns > WINDOW_S * 1e9:
            self._past.popleft()
        return self._past[0]

    def _learned(self, name: str) -> dict[str, Any] | None:
        """What ``name`` is learning in flight (the hard iron: value, uncertainty, whether
        applied), as of its last update; None when it learns nothing."""
        dev = self.pipeline.devices.get(name) if self.pipeline is not None else None
        learner = dev.mag_learner if dev is not None else None
        return None if learner is None else dict(learner.latest)

    def _learned_accel(self, name: str) -> dict[str, Any] | None:
        """The accelerometer offset ``name`` is learning in flight (body frame, mg, with
        its uncertainty and the axes applied), as of its last update; None when it learns
        none."""
        dev = self.pipeline.devices.get(name) if self.pipeline is not None else None
        teacher = dev.accel_teacher if dev is not None else None
        return None if teacher is None else dict(teacher.learner.latest)

    def _health(self, copy: Copy, past: _Past | None) -> dict[str, Any]:
        names = list(self._drivers) + [n for n in copy.devices if n not in self._drivers]
        span_s = (copy.t_ns - past.t_ns) / 1e9 if past is not None and copy.t_ns else 0.0
        return {name: self._device_health(name, copy, past, span_s) for name in names}

    def _device_health(self, name: str, copy: Copy, past: _Past | None,
                       span_s: float) -> dict[str, Any]:
        """One device's rates, errors, staleness and the problems that make it faulty."""
        d = copy.devices.get(name)
        # read at every snapshot: a device that joins late or comes back reconfigured
        # has its streams then
        configured = {} if self.pipeline is None else configured_rates_hz(self.pipeline, name)
        achieved = _achieved_hz(d, past.counts.get(name, {}) if past is not None else None,
                                span_s)
        fastest = max(configured.values(), default=None)
        stale_after = max(STALE_PERIODS / fastest if fastest else 0.0, STALE_MIN_S)
        last_t = None if d is None or d.last_t_ns is None else d.last_t_ns / 1e9
        now_t = None if copy.t_ns is None else copy.t_ns / 1e9
        stale = now_t is not None and (last_t is None or now_t - last_t > stale_after)
        recent = _Recent.of(d, name, past, self._faults(name))
        problems = []
        if stale:
            problems.append("stale: no sample for "
                            + (f"{now_t - last_t:.1f} s" if last_t is not None and
                               now_t is not None else "the whole run"))
        problems += recent.problems()
        problems += [f"{channel} at {achieved[channel]:.0f} of {want:g} Hz"
                     for channel, want in configured.items()
                     if channel in achieved and achieved[channel] < RATE_LOW * want]
        if recent.flags > FLAGGED_FAULTY * max(recent.samples, 1):
            problems.append(f"{recent.flags} of {recent.samples} samples flagged in the "
                            f"last {WINDOW_S:g} s")
        errors = self._errors(name)
        return {
            "driver": self._drivers.get(name),
            "configured_hz": configured,
            "achieved_hz": achieved,
            "samples": sum(d.counts.values()) if d is not None else 0,
            "flagged": dict(d.flagged) if d is not None else {},
            "flagged_recent": recent.flags,
            "bus_errors": errors[0],
            "device_errors": errors[1],
            "learned": self._learned(name),
            "learned_accel": self._learned_accel(name),
            "last_t_s": last_t,
            "stale": stale,
            "faulty": bool(problems) and not (stale and len(problems) == 1),
            "problems": problems,
        }

    def _errors(self, name: str) -> tuple[int, int]:
        """The device's bus and device error counts (0, 0 before it is opened)."""
        dev = self.pipeline.devices.get(name) if self.pipeline is not None else None
        return (0, 0) if dev is None else (dev.bus_errors, dev.device_errors)

    def _bringup(self, copy: Copy, past: _Past | None) -> dict[str, Any]:
        """The rotation each sensor saw in the last window and, for each bring-up motion,
        its verdict (the page latches the first clear verdict after the user starts one)."""
        evidence: list[Evidence] = []
        if past is not None:
            evidence += _gyro_evidence(copy, past)
            evidence += self._vector_evidence(copy, past)
        return {
            "window_s": WINDOW_S,
            "window_start_t_s": None if past is None else past.t_ns / 1e9,
            "seen": [{"device": e.device, "channel": e.channel.value,
                      "rotation_deg": list(e.rotation_deg)} for e in evidence],
            "verdicts": {m.key: [judge(m, e).as_dict() for e in evidence] for m in MOTIONS},
            "motions": [{"key": m.key, "label": m.label, "prompt": m.prompt}
                        for m in MOTIONS],
        }

    def _vector_evidence(self, copy: Copy, past: _Past) -> list[Evidence]:
        """The rotation between each accelerometer's and magnetometer's mean vector at the
        start and at the end of the window (ENDS_S long each)."""
        ends_ns = ENDS_S * 1e9
        first = [p for p in self._past if p.t_ns - past.t_ns <= ends_ns]
        last = [p for p in self._past if copy.t_ns is not None
                and copy.t_ns - p.t_ns <= ends_ns]
        keys = {k for p in first for k in p.vectors} & {k for p in last for k in p.vectors}
        evidence = []
        for key in sorted(keys, key=lambda k: (k[0], k[1].value)):
            v0 = mean_vector([p.vectors[key] for p in first if key in p.vectors])
            v1 = mean_vector([p.vectors[key] for p in last if key in p.vectors])
            n0 = math.sqrt(sum(c * c for c in v0)) or 1.0
            evidence.append(Evidence(key[0], key[1], rotation_between(v0, v1),
                                     (v0[0] / n0, v0[1] / n0, v0[2] / n0)))
        return evidence


def _gyro_evidence(copy: Copy, past: _Past) -> list[Evidence]:
    """The rotation each gyro integrated over the window, in degrees about body x, y, z."""
    evidence = []
    for name, d in copy.devices.items():
        before = past.rotation.get(name)
        if before is not None and d.last_gyro_ns is not None:
            evidence.append(Evidence(name, Quantity.GYRO, (
                math.degrees(d.rotation_rad[0] - before[0]),
                math.degrees(d.rotation_rad[1] - before[1]),
                math.degrees(d.rotation_rad[2] - before[2]))))
    return evidence


def _achieved_hz(d: Any, before: dict[Quantity, int] | None, span_s: float) -> dict[str, float]:
    """Samples per second of pipeline time of each channel since ``before`` (the counts at
    the start of the window); empty until the window spans half a second."""
    if d is None or before is None or span_s < 0.5:
        return {}
    return {channel.value: (n - before.get(channel, 0)) / span_s
            for channel, n in d.counts.items()}


@dataclass(frozen=True)
class _Recent:
    """A device's faults, flagged samples and samples within the window."""

    faults: int
    flags: int
    samples: int

    @classmethod
    def of(cls, d: Any, name: str, past: _Past | None, faults: int) -> _Recent:
        if past is None:
            return cls(faults, sum(d.flagged.values()) if d is not None else 0,
                       sum(d.counts.values()) if d is not None else 0)
        recent_faults = faults - past.faults.get(name, 0)
        if d is None:
            return cls(recent_faults, 0, 0)
        return cls(recent_faults, sum(d.flagged.values()) - past.flagged.get(name, 0),
                   sum(d.counts.values()) - sum(past.counts.get(name, {}).values()))

    def problems(self) -> list[str]:
        return ([f"{self.faults} bus/device errors in the last {WINDOW_S:g} s"]
                if self.faults > 0 else [])


def _attitude(a: Any) -> dict[str, Any]:
    roll, pitch, yaw = a.roll_pitch_yaw_deg
    return {"t_s": a.t_ns / 1e9, "roll_deg": roll, "pitch_deg": pitch,
            "heading_deg": yaw % 360.0, "q_body_to_ned": list(a.q_body_to_ned)}


def _sensors(valid: dict[Quantity, Sample], latest: dict[Quantity, Sample]) -> dict[str, Any]:
    out: dict[str, Any] = {}
    for channel, sample in latest.items():
        good = valid.get(channel)
        entry: dict[str, Any] = {"unit": channel.unit, "t_s": sample.t_ns / 1e9,
                                 "valid": sample.valid, "value": None}
        if good is not None:
            entry["value_t_s"] = good.t_ns / 1e9
            if isinstance(good, VectorSample):
                entry["value"] = [_finite(v) for v in good.vector]
                entry["frame"] = good.frame.value
            elif isinstance(good, ScalarSample):
                entry["value"] = _finite(good.scalar)
        out[channel.value] = entry
    return out


def _finite(x: float) -> float | None:
    return float(x) if math.isfinite(x) else None
