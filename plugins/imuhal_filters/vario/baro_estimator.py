"""``baro-vario``: altitude and climb rate from the barometer alone (2-state Kalman filter)."""

from __future__ import annotations

import math
from typing import Any, ClassVar

from pydantic import Field

from imuhal.core.atmosphere import SEA_LEVEL_PRESSURE_PA
from imuhal.core.gaps import StreamGap
from imuhal.core.quantities import Quantity
from imuhal.core.samples import PressureSample
from imuhal.estimation.base import Estimator, EstimatorSettings
from imuhal.estimation.outputs import (
    Estimate,
    EstimateFlag,
    RejectedEstimate,
    VerticalEstimate,
)
from imuhal_filters.common.gaps import CountedGaps, Step
from imuhal_filters.vario.baro_input import dt_s, usable_altitude_m
from imuhal_filters.vario.baro_kalman import BaroKalman2
from imuhal_filters.vario.gate import InnovationGate


class BaroVarioSettings(EstimatorSettings):
    """Tuning of the barometer-only filter. SI units.

    ``accel_noise_m_s2`` is the standard deviation of the vertical acceleration the
    constant-velocity model does not know about (air movement and pilot input), not a sensor
    noise: larger values follow climb-rate changes faster but pass more baro noise into the
    climb rate. ``altitude_noise_m`` is the barometer's altitude noise (estimate it with
    ``estimate_altitude_variance`` on 1-2 s of data at rest and take the square root).

    The defaults are close to the kf3 ``esp32`` defaults (sigma_z^2 = 300 cm^2,
    sigma_a^2 = 50000 cm^2/s^4, i.e. 0.17 m and 2.2 m/s^2) so the two filters start from the
    same idea of the air. On the 40 Hz paraglider data set C the barometer-only filter's
    climb-rate error is smallest for sigma_a around 2-3 m/s^2.
    """

    accel_noise_m_s2: float = Field(default=2.0, gt=0.0)
    """Sigma of unmodelled vertical acceleration (m/s^2)."""
    altitude_noise_m: float = Field(default=0.2, gt=0.0)
    """Sigma of the barometric altitude measurement (m)."""
    sea_level_pa: float = Field(default=SEA_LEVEL_PRESSURE_PA, gt=0.0)
    """Pressure reference (QNH, Pa) for pressure -> altitude; 101325 gives pressure altitude."""
    initial_climb_sigma_m_s: float = Field(default=5.0, gt=0.0)
    """Sigma of the climb rate at start-up and after a restart (m/s); the filter starts at
    0 m/s. Nobody measured it and the board may be flying (a brown-out reboot in the air):
    5 m/s covers a paraglider's or a glider's strong thermals and ordinary sink, as vario-kf3's
    UNKNOWN_CLIMB_SIGMA_M_S. (1 m/s, a board at rest, handed out climb 0 in a 1 m/s climb.)"""
    settled_climb_sigma_m_s: float = Field(default=0.4, gt=0.0)
    """Estimates are withheld (UNSETTLED) after a start or a restart until the filter's own
    climb-rate sigma is below this (m/s). It must lie above the filter's steady state
    (0.19 m/s at 50 Hz, 0.26 m/s at 25 Hz with the default noises): about 0.3 s at 50 Hz."""
    max_gap_s: float = Field(default=1.0, gt=0.0)
    """A gap between valid samples longer than this restarts the filter from the new sample:
    the constant-velocity prediction over a long outage is not worth trusting."""
    max_dt_s: float = Field(default=0.25, gt=0.0)
    """A step between valid samples longer than this is predicted over only when the
    pipeline counted the pressures lost in it (a StreamGap, imuhal.core.gaps); one that no
    counted loss explains (a time stamp that jumped) restarts the filter instead."""
    innovation_gate_sigma: float | None = Field(default=5.0, gt=0.0)
    """A barometric altitude further than this many standard deviations of the innovation
    (sqrt(P_zz + sigma_z^2)) from the prediction is not fused (counted as ``gated``): one
    wild but in-range pressure, valid by design (docs/reliability.md), must not throw the
    climb rate. None: no gate (the seed's filter)."""
    innovation_gate_min_m: float = Field(default=1.0, ge=0.0)
    """The gate never closes for innovations within this (m): a barometer noisier than
    ``altitude_noise_m`` says must not be gated on its ordinary noise."""
    gate_reacquire_s: float = Field(default=0.3, gt=0.0)
    """Altitudes rejected without a break for this long are a real change of level (a QNH
    change, a climb faster than the model follows): the filter re-acquires the new level."""


class BaroVarioEstimator(Estimator):
    """Barometer-only variometer: one predict + update per valid PressureSample.

    Emits a VerticalEstimate (altitude m up +, climb m/s up +, ``accel_bias_m_s2`` None) for
    every fused sample once the climb rate is known (``settled_climb_sigma_m_s``); before, from
    the first sample (which only initialises: altitude = measurement, climb = 0 with
    ``initial_climb_sigma_m_s``), a RejectedEstimate flagged UNSETTLED. Flagged samples,
    samples with non-positive or non-finite pressure, and samples whose timestamp does not
    advance are skipped and counted in ``diagnostics()``.
    """

    name: ClassVar[str] = "baro-vario"
    description: ClassVar[str] = (
        "Altitude and climb rate from the barometer only (2-state constant-velocity Kalman)"
    )
    Settings: ClassVar[type[EstimatorSettings]] = BaroVarioSettings
    consumes: ClassVar[tuple[type, ...]] = (PressureSample, StreamGap)
    settings: BaroVarioSettings

    def reset(self) -> None:
        s = self.settings
        self._kf = BaroKalman2(accel_var=s.accel_noise_m_s2**2, meas_var=s.altitude_noise_m**2)
        self._last_t_ns: int | None = None
        self._counts = {"fused": 0, "skipped_invalid": 0, "skipped_non_monotonic": 0,
                        "restarts_after_gap": 0, "steps_over_counted_gaps": 0,
                        "gated": 0, "reacquired": 0}
        self._gaps = CountedGaps((Quantity.PRESSURE,))
        self._gate = InnovationGate(s.innovation_gate_sigma, s.innovation_gate_min_m,
                                    s.gate_reacquire_s)
        self._withheld = 0
        """Estimates withheld while the gate refused most altitudes or the climb rate was not
        yet known (UNSETTLED)."""
        self._settling = False
        """Started or restarted and the climb sigma not yet under settled_climb_sigma_m_s."""

    # -- the filter steps, kept apart so callers (and tests) can drive them directly --------

    def initialise(self, t_ns: int, altitude_m: float) -> None:
        s = self.settings
        self._kf.initialise(altitude_m, 0.0, s.altitude_noise_m**2, s.initial_climb_sigma_m_s**2)
        self._settling = True
        self._last_t_ns = t_ns

    def predict(self, dt_seconds: float) -> None:
        """Propagate the state ``dt_seconds`` ahead (constant velocity)."""
        self._kf.predict(dt_seconds)

    def update(self, altitude_m: float) -> float:
        """Fuse one barometric altitude (m); return the innovation (m)."""
        return self._kf.update(altitude_m)

    # -- Estimator interface ----------------------------------------------------------------

    def process(self, item: Any) -> list[Estimate]:
        if isinstance(item, StreamGap):
            self._gaps.note(item)
            return []
        if not isinstance(item, PressureSample):
            return []
        altitude = usable_altitude_m(item, self.settings.sea_level_pa)
        if altitude is None:
            self._counts["skipped_invalid"] += 1
            return []
        innovation = 0.0
        if self._last_t_ns is None:
            self.initialise(item.t_ns, altitude)
        else:
            dt = dt_s(item.t_ns, self._last_t_ns)
            if dt <= 0.0:
                self._counts["skipped_non_monotonic"] += 1
                return []
            step = self._gaps.step(item.t_ns, dt, self.settings.max_dt_s,
                                   self.settings.max_gap_s)
            if step is Step.RESTART:
                self._counts["restarts_after_gap"] += 1
                self.initialise(item.t_ns, altitude)
            else:
                self._counts["steps_over_counted_gaps"] += step is Step.OVER_GAP
                self.predict(dt)
                self._last_t_ns = item.t_ns
                innovation = altitude - self._kf.z
                if not self._accept(item.t_ns, altitude, innovation):
                    return [self._estimate(item.t_ns, innovation, gated=True)]
                innovation = self.update(altitude)
        self._counts["fused"] += 1
        return [self._estimate(item.t_ns, innovation)]

    def _accept(self, t_ns: int, altitude_m: float, innovation_m: float) -> bool:
        """The innovation gate (``imuhal_filters.vario.gate``): False (counted) to skip this
        altitude's update. A new level is taken keeping the climb rate."""
        kf = self._kf

        def reacquire() -> None:
            kf.z = altitude_m
            kf.pzz, kf.pzv = kf.meas_var, 0.0

        return self._gate.accept(t_ns, innovation_m, kf.pzz, kf.meas_var, 1.0, reacquire,
                                 self._counts)

    def _estimate(self, t_ns: int, innovation_m: float, *, gated: bool = False
                  ) -> Estimate:
        """The estimate after this altitude, or, while the gate refuses most altitudes
        (``InnovationGate.unsettled``) or after a start or restart until the climb rate is
        known (``settled_climb_sigma_m_s``), a RejectedEstimate withholding it (UNSETTLED)."""
        if self._settling:
            self._settling = self._kf.pvv > self.settings.settled_climb_sigma_m_s**2
        if self._gate.unsettled or self._settling:
            self._withheld += 1
            return RejectedEstimate(t_ns=t_ns, source=self.instance, kind="vertical",
                                    flags=EstimateFlag.UNSETTLED, estimator=self.name)
        kf = self._kf
        return VerticalEstimate.build(  # (the keyword constructor, through its slots)
            t_ns,
            self.instance,
            kf.z,
            kf.v,
            None,
            {
                "innovation_m": innovation_m,
                "altitude_gated": gated,
                "altitude_sigma_m": math.sqrt(max(kf.pzz, 0.0)),
                "climb_sigma_m_s": math.sqrt(max(kf.pvv, 0.0)),
                **self._counts,
            },
        )

    def get_state(self) -> dict[str, Any]:
        return {"kf": self._kf.as_dict(), "last_t_ns": self._last_t_ns,
                "counts": dict(self._counts),
                "gate": self._gate.as_dict(), "withheld": self._withheld,
                "settling": self._settling}

    def set_state(self, state: dict[str, Any]) -> None:
        self._kf.load_dict(state["kf"])
        last = state["last_t_ns"]
        self._last_t_ns = None if last is None else int(last)
        self._counts = {k: int(v) for k, v in state["counts"].items()}
        self._gate.load_dict(state.get("gate") or {})
        self._withheld = int(state.get("withheld", 0))
        self._settling = bool(state.get("settling", False))

    def diagnostics(self) -> dict[str, Any]:
        return {**self._counts, "withheld_unsettled": self._withheld}
