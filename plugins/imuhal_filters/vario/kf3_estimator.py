"""``vario-kf3``: altitude, climb rate and accelerometer bias from barometer + AHRS.

Inputs (project units, converted to the cm-unit core at this boundary only):

- PressureSample -> ISA altitude (m). Each valid one runs one filter step.
- AttitudeEstimate with ``linear_accel_ned_m_s2``: the upward acceleration is ``-a_ned[2]``.
- AttitudeEstimate without it: its quaternion is kept, and each valid body-frame AccelSample
  is rotated into NED and gravity-compensated (``imuhal.estimation.gravity``) with the latest
  quaternion. Once any AttitudeEstimate has carried a linear acceleration, AccelSamples are
  ignored so the same acceleration is never counted twice.

The IMU-rate upward accelerations are averaged over each barometer interval (low-pass and
down-sample, as the seed does) and the filter runs predict(mean accel, dt) then update(altitude)
once per valid pressure sample, dt from the pressure samples' ``t_ns``. The acceleration paired
with a barometer sample is the mean over the interval that sample closes (the seed author's
firmware pairs it with the previous interval's mean instead; on the author's log the
innovation was no better either way, and the current interval is the one the prediction
integrates across: docs/estimators.md, "Timing").

The first valid pressure sample initialises (altitude = measurement, climb 0, bias =
initial_bias) and, as in the references, also gets its own predict/update step with the
acceleration that came with it. Unlike the references, the climb rate starts with the
variance of a climb rate nobody measured (``initial_climb_sigma_m_s``, by default
kf3_settings.UNKNOWN_CLIMB_SIGMA_M_S, not the references' 1 cm/s of a board known to be at
rest), and the estimates are withheld (UNSETTLED) until the altitudes have brought its
standard deviation under SETTLED_CLIMB_SIGMA_M_S: a board switched on in flight (a brown-out
reboot, a battery swap in the air) handed out climb 0.0 in a 1.07 m/s climb as valid, and a
second later 2.2 m/s against 1.17 (the altitudes' slope went into the bias while the climb
rate was trusted at 0).

The references know their fixed period; here the step length is only known at the second
sample, so the first sample's step runs then, just before the second one's (the estimate
emitted at the first sample is the initial state).

Innovation gate: an altitude further than ``innovation_gate_sigma`` standard deviations of
the innovation from the prediction is not fused (counted ``gated``); if altitudes keep being
rejected for ``gate_reacquire_s``, the level really changed and the filter re-acquires it
(altitude reset to the measurement, climb and bias kept; counted ``reacquired``).

An interval with no acceleration at all predicts with zero true acceleration (a_meas = bias
estimate), i.e. it falls back to the constant-velocity model, and is counted.
"""

from __future__ import annotations

import math
from typing import Any, ClassVar

from imuhal.core.atmosphere import STANDARD_GRAVITY_M_S2
from imuhal.core.gaps import StreamGap
from imuhal.core.quantities import Quantity
from imuhal.core.samples import AccelSample, Frame, PressureSample
from imuhal.estimation.base import Estimator, EstimatorSettings
from imuhal.estimation.gravity import vertical_accel_up_m_s2
from imuhal.estimation.outputs import (
    AttitudeBlock,
    AttitudeEstimate,
    Estimate,
    EstimateFlag,
    RejectedEstimate,
    VerticalEstimate,
)
from imuhal_filters.common.gaps import CountedGaps, Step
from imuhal_filters.vario.baro_input import dt_s, usable_altitude_m
from imuhal_filters.vario.downsample import IntervalMean
from imuhal_filters.vario.gate import InnovationGate
from imuhal_filters.vario.kf3 import Kalman3
from imuhal_filters.vario.kf3_settings import (
    CM_PER_M,
    UNKNOWN_CLIMB_SIGMA_M_S,
    VarioKf3Settings,
    configured_core,
    initial_climb_variance_cm2_s2,
)

_COUNTERS = (
    "fused",
    "skipped_invalid",
    "skipped_non_monotonic",
    "restarts_after_gap",
    "steps_over_counted_gaps",
    "accel_samples_skipped_invalid",
    "accel_samples_skipped_frame",
    "accel_samples_without_attitude",
    "intervals_without_accel",
    "intervals_accel_held",
    "gated",
    "reacquired",
)


SETTLED_CLIMB_SIGMA_M_S = 0.25
"""At start-up, after a restart after a gap (and after an interval without acceleration,
UNMEASURED_ACCEL_SIGMA_M_S2), estimates are withheld (UNSETTLED) until the filter's own
climb-rate standard deviation is below this (m/s): about 0.8 s of altitudes at 50 Hz from
UNKNOWN_CLIMB_SIGMA_M_S with the default tuning, 0.2 s after an unmeasured interval. The
default of the ``settled_climb_sigma_m_s`` setting, which a tuning whose steady climb sigma
lies above it must raise (the default tuning's: 0.036 m/s at 50 Hz)."""

UNMEASURED_ACCEL_SIGMA_M_S2 = STANDARD_GRAVITY_M_S2
"""An interval without any acceleration (the AHRS withheld or lost its estimates) predicts
with zero true acceleration, but the true one is unknown: within a g either way (a glider's
or a small aircraft's manoeuvres), added to the climb rate's variance for the interval, and
the estimates are withheld (UNSETTLED) until the altitudes have brought the climb rate's
sigma back under SETTLED_CLIMB_SIGMA_M_S. A constant-velocity prediction through a
take-off's climb-out lagged the truth by more than 3 m/s with nothing flagged (the fault
matrix, seed-rc-vario, wild values at 10 %: the IMU's samples spent settling)."""

_HOLD_S = 0.1
"""An interval without acceleration reuses the previous interval's mean when it ended at most
this long before (s); older, the prediction assumes zero true acceleration."""


class VarioKf3Estimator(Estimator):
    """The seed's 3-state variometer Kalman filter (see ``imuhal_filters.vario.kf3``)."""

    name: ClassVar[str] = "vario-kf3"
    description: ClassVar[str] = (
        "Altitude, climb rate and accelerometer bias: barometer fused with AHRS vertical "
        "acceleration (3-state Kalman, Nair 2016)"
    )
    Settings: ClassVar[type[EstimatorSettings]] = VarioKf3Settings
    consumes: ClassVar[tuple[type, ...]] = (PressureSample, AttitudeEstimate, AccelSample,
                                            StreamGap)
    settings: VarioKf3Settings

    def reset(self) -> None:
        self._attitude_source = self.settings.attitude_source
        self._kf: Kalman3 | None = None
        self._last_t_ns: int | None = None
        self._gaps = CountedGaps((Quantity.PRESSURE,))
        self._accel = IntervalMean()
        self._q: tuple[float, float, float, float] | None = None
        self._attitude_has_linear_accel = False
        self._counts = dict.fromkeys(_COUNTERS, 0)
        self._first: tuple[float, float | None] | None = None
        """The first sample's (altitude m, mean accel m/s^2), waiting for its step length."""
        s = self.settings
        self._gate = InnovationGate(s.innovation_gate_sigma, s.innovation_gate_min_m,
                                    s.gate_reacquire_s)
        self._withheld = 0
        """Estimates withheld while the gate refused most altitudes (UNSETTLED)."""
        self._settling = False
        """Started or restarted and the climb rate not yet known to SETTLED_CLIMB_SIGMA_M_S."""
        self._unmeasured = 0.0
        """The length (s) of the interval just predicted without any acceleration."""
        self._held: tuple[int, float] | None = None
        """The last interval's (end ns, mean accel m/s^2): an AHRS slower than the barometer
        (the Freescale filters' Kalman steps at 31 Hz against 50 Hz) leaves intervals empty."""

    # -- the filter steps, in project units -------------------------------------------------

    def initialise(self, t_ns: int, altitude_m: float) -> None:
        """Start from ``altitude_m`` with climb 0 +- ``initial_climb_sigma_m_s`` (by default
        UNKNOWN_CLIMB_SIGMA_M_S: the board may be flying) and withhold the estimates until
        the climb rate is known."""
        self._kf = configured_core(self.settings, altitude_m)
        self._kf.P[1, 1] = initial_climb_variance_cm2_s2(self.settings)
        # the references' start (initial_climb_sigma_m_s None) assumes a board at rest
        self._settling = self.settings.initial_climb_sigma_m_s is not None
        self._last_t_ns = t_ns
        self._gate.forget()
        # the references' first step uses the acceleration that came with the first altitude
        self._first = (altitude_m, self._accel.take())

    def _restart_after_gap(self, t_ns: int, altitude_m: float) -> None:
        """Start again from ``altitude_m`` after a gap: the gap lost the altitude and the
        climb rate, not the accelerometer's bias. The bias (and its variance) are kept and
        the climb rate starts at 0 with UNKNOWN_CLIMB_SIGMA_M_S, so the altitudes after the gap
        correct the climb rate, not the bias (with the start-up covariance, which trusts
        climb 0, a restart in a 1 m/s sink drove the bias to 13 m/s^2 and the climb rate
        4 m/s off: the fault matrix, seed-gps-vario, chip resets)."""
        kf = self._kf
        assert kf is not None
        bias, bias_variance = float(kf.x[2]), float(kf.P[2, 2])
        self.initialise(t_ns, altitude_m)
        kf = self._kf
        assert kf is not None
        kf.x[2] = bias
        kf.P[2, 2] = bias_variance
        kf.P[1, 1] = (UNKNOWN_CLIMB_SIGMA_M_S * CM_PER_M) ** 2
        self._settling = True

    def _widen_for_unmeasured_accel(self, dt: float) -> None:
        """The covariance of ``dt`` s of an acceleration nobody measured
        (UNMEASURED_ACCEL_SIGMA_M_S2, white over the interval) added to the prediction's, and
        the estimates withheld until the climb rate is known again."""
        kf = self._kf
        assert kf is not None
        sa2 = (UNMEASURED_ACCEL_SIGMA_M_S2 * CM_PER_M) ** 2
        dt2 = dt * dt
        kf.P[0, 0] += 0.25 * dt2 * dt2 * sa2
        kf.P[0, 1] += 0.5 * dt2 * dt * sa2
        kf.P[1, 0] += 0.5 * dt2 * dt * sa2
        kf.P[1, 1] += dt2 * sa2
        self._settling = True

    def predict(self, accel_up_m_s2: float, dt_seconds: float) -> None:
        """Propagate ``dt_seconds`` with the interval's mean upward acceleration (m/s^2)."""
        assert self._kf is not None, "initialise first"
        self._kf.predict(accel_up_m_s2 * CM_PER_M, dt_seconds)

    def update(self, altitude_m: float) -> float:
        """Fuse one barometric altitude (m); return the innovation (m)."""
        assert self._kf is not None, "initialise first"
        return self._kf.update(altitude_m * CM_PER_M) / CM_PER_M

    # -- Estimator interface ----------------------------------------------------------------

    def process(self, item: Any) -> list[Estimate]:
        if type(item) is AttitudeEstimate:  # the common case: one per gyro sample
            self._on_attitude(item)
            return []
        if isinstance(item, PressureSample):
            return self._on_pressure(item)
        if isinstance(item, AttitudeEstimate):
            self._on_attitude(item)
        elif isinstance(item, AccelSample):
            self._on_accel(item)
        elif isinstance(item, StreamGap):
            self._gaps.note(item)
        return []

    def update_estimate_block(self, block: AttitudeBlock) -> list[Estimate]:
        """An AHRS's attitude block (``Estimator.update_estimate_block``) on its columns:
        the accelerations added in the order of its rows, as ``process()`` adds them; an
        attitude estimate makes no estimate here."""
        wanted = self._attitude_source
        if wanted is not None and block.source != wanted:
            return []
        lin = block.linear_accel_ned_m_s2
        if lin is None:
            self._q = block.rows()[-1].q_body_to_ned  # each row replaces the one before
            return []
        self._attitude_has_linear_accel = True
        add = self._accel.add
        for down in lin[:, 2].tolist():  # NED z is down
            add(-down)
        return []

    def _on_attitude(self, att: AttitudeEstimate) -> None:
        wanted = self._attitude_source
        if wanted is not None and att.source != wanted:
            return
        lin = att.linear_accel_ned_m_s2
        if lin is not None:
            self._attitude_has_linear_accel = True
            self._accel.add(-float(lin[2]))  # NED z is down
        else:
            self._q = att.q_body_to_ned

    def _on_accel(self, sample: AccelSample) -> None:
        if self._attitude_has_linear_accel:
            return  # the AHRS already hands us this acceleration, compensated
        if not sample.valid:
            self._counts["accel_samples_skipped_invalid"] += 1
        elif sample.frame is not Frame.BODY_NED:
            self._counts["accel_samples_skipped_frame"] += 1
        elif self._q is None:
            self._counts["accel_samples_without_attitude"] += 1
        else:
            self._accel.add(vertical_accel_up_m_s2(self._q, sample.accel_m_s2))

    def _on_pressure(self, sample: PressureSample) -> list[Estimate]:
        altitude = usable_altitude_m(sample, self.settings.sea_level_pa)
        if altitude is None:
            self._counts["skipped_invalid"] += 1
            return []
        innovation = 0.0
        if self._kf is None or self._last_t_ns is None:
            self.initialise(sample.t_ns, altitude)
        else:
            dt = dt_s(sample.t_ns, self._last_t_ns)
            if dt <= 0.0:
                self._counts["skipped_non_monotonic"] += 1
                return []
            step = self._gaps.step(sample.t_ns, dt, self.settings.max_dt_s,
                                   self.settings.max_gap_s)
            if step is Step.RESTART:
                self._counts["restarts_after_gap"] += 1
                self._restart_after_gap(sample.t_ns, altitude)
            else:
                self._counts["steps_over_counted_gaps"] += step is Step.OVER_GAP
                accel = self._accel.take()
                held = self._held
                if accel is not None:
                    self._held = (sample.t_ns, accel)
                elif held is not None and (sample.t_ns - held[0]) * 1e-9 <= _HOLD_S:
                    # no estimate in this interval: the AHRS runs slower than the barometer;
                    # zero would drop a climb step's acceleration every other interval
                    # (freescale-9dof: 90 % of a 2 m/s step 0.76 s late instead of 0.02 s)
                    accel = held[1]
                    self._counts["intervals_accel_held"] += 1
                else:
                    self._counts["intervals_without_accel"] += 1
                    accel = self._kf.bias / CM_PER_M  # zero true acceleration
                    self._unmeasured = dt
                if self._first is not None:
                    z0, a0 = self._first
                    self._first = None
                    self.predict(self._kf.bias / CM_PER_M if a0 is None else a0, dt)
                    self.update(z0)
                self.predict(accel, dt)
                if self._unmeasured:
                    self._widen_for_unmeasured_accel(self._unmeasured)
                    self._unmeasured = 0.0
                self._last_t_ns = sample.t_ns
                innovation = altitude - self._kf.z / CM_PER_M
                if not self._accept(sample.t_ns, altitude, innovation):
                    return [self._estimate(sample.t_ns, innovation, gated=True)]
                innovation = self.update(altitude)
        self._counts["fused"] += 1
        return [self._estimate(sample.t_ns, innovation)]

    def _accept(self, t_ns: int, altitude_m: float, innovation_m: float) -> bool:
        """The innovation gate (``imuhal_filters.vario.gate``): False (counted) to skip this
        altitude's update. A new level is taken keeping climb and bias."""
        kf = self._kf
        assert kf is not None

        def reacquire() -> None:
            kf.x[0] = altitude_m * CM_PER_M
            kf.P[0, :] = 0.0
            kf.P[:, 0] = 0.0
            kf.P[0, 0] = kf.z_meas_variance

        return self._gate.accept(t_ns, innovation_m, kf.P[0, 0], kf.z_meas_variance, CM_PER_M,
                                 reacquire, self._counts)

    def _estimate(self, t_ns: int, innovation_m: float, *, gated: bool = False
                  ) -> Estimate:
        """The estimate after this altitude, or, while the gate refuses most altitudes
        (``InnovationGate.unsettled``) or after a start or a restart after a gap until the
        climb rate is known (SETTLED_CLIMB_SIGMA_M_S), a RejectedEstimate withholding it
        (UNSETTLED)."""
        if self._settling and self._kf is not None:
            bound_cm_s = self.settings.settled_climb_sigma_m_s * CM_PER_M
            self._settling = bool(self._kf.P[1, 1] > bound_cm_s**2)
        if self._gate.unsettled or self._settling:
            self._withheld += 1
            return RejectedEstimate(t_ns=t_ns, source=self.instance, kind="vertical",
                                    flags=EstimateFlag.UNSETTLED, estimator=self.name)
        kf = self._kf
        assert kf is not None
        p = kf.P
        return VerticalEstimate.build(  # (the keyword constructor, through its slots)
            t_ns,
            self.instance,
            kf.z / CM_PER_M,
            kf.v / CM_PER_M,
            kf.bias / CM_PER_M,
            {
                "innovation_m": innovation_m,
                "altitude_gated": gated,
                "altitude_sigma_m": math.sqrt(max(p[0, 0], 0.0)) / CM_PER_M,
                "climb_sigma_m_s": math.sqrt(max(p[1, 1], 0.0)) / CM_PER_M,
                "bias_sigma_m_s2": math.sqrt(max(p[2, 2], 0.0)) / CM_PER_M,
                "accel_variance_m2_s4": kf.accel_variance / CM_PER_M**2,
                **self._counts,
            },
        )

    def get_state(self) -> dict[str, Any]:
        return {
            "kf": None if self._kf is None else self._kf.as_dict(),
            "last_t_ns": self._last_t_ns,
            "accel": self._accel.as_dict(),
            "q": None if self._q is None else list(self._q),
            "attitude_has_linear_accel": self._attitude_has_linear_accel,
            "counts": dict(self._counts),
            "first": None if self._first is None else list(self._first),
            "gate": self._gate.as_dict(), "withheld": self._withheld,
            "settling": self._settling,
            "held": None if self._held is None else list(self._held),
        }

    def set_state(self, state: dict[str, Any]) -> None:
        if state["kf"] is None:
            self._kf = None
        else:
            self._kf = Kalman3(self.settings.mode)
            self._kf.load_dict(state["kf"])
        last = state["last_t_ns"]
        self._last_t_ns = None if last is None else int(last)
        self._accel.load_dict(state["accel"])
        q = state["q"]
        self._q = None if q is None else (float(q[0]), float(q[1]), float(q[2]), float(q[3]))
        self._attitude_has_linear_accel = bool(state["attitude_has_linear_accel"])
        self._counts = {**dict.fromkeys(_COUNTERS, 0),
                        **{k: int(v) for k, v in state["counts"].items()}}
        first = state.get("first")
        self._first = None if first is None else (float(first[0]), first[1])
        self._gate.load_dict(state.get("gate") or {})
        self._withheld = int(state.get("withheld", 0))
        self._settling = bool(state.get("settling", False))

        held = state.get("held")
        self._held = None if held is None else (int(held[0]), float(held[1]))

    def diagnostics(self) -> dict[str, Any]:
        return {**self._counts, "withheld_unsettled": self._withheld}
