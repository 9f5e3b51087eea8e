"""Base class of the AHRS estimators: turns a stream of samples into one filter step per gyro.

What every AHRS plugin shares lives here so the filters themselves are only their kernels:

- gyro, accelerometer and magnetometer samples arrive separately; the estimator keeps the
  latest valid accel and mag and runs one step per valid gyro sample with them (an accel or mag
  older than ``max_aux_age_s`` is not used);
- invalid samples (``sample.valid`` False) are never fused: they are counted per channel;
- the step length comes from consecutive gyro timestamps (or the nominal ``sample_period_s``
  for the first step, for gaps longer than ``max_dt_s`` and for non-increasing timestamps);
- accelerometer values are handed to the kernel gravity positive in g (the unit of the
  reference code), magnetometer values in uT, gyro in rad/s, all in body NED axes;
- each step emits an :class:`AttitudeEstimate` with the body -> NED quaternion and, when an
  accel sample is at hand, the gravity-compensated acceleration in NED (m/s^2);
- the state (quaternion, held samples, counters, filter internals) can be saved and restored.

Subclasses implement ``_reset_filter``, ``_step``, ``_filter_state`` and ``_set_filter_state``
and expose their quaternion through ``_q``.
"""

from __future__ import annotations

from abc import abstractmethod
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np
from pydantic import Field

from imuhal.core.frames import FloatArray
from imuhal.core.samples import (
    AccelSample,
    Channel,
    Frame,
    GyroSample,
    MagSample,
    Sample,
)
from imuhal.estimation.base import Estimator, EstimatorSettings
from imuhal.estimation.gravity import linear_accel_ned_m_s2
from imuhal.estimation.outputs import AttitudeEstimate, Estimate
from imuhal_filters.common.gate import gravity_positive_g
from imuhal_filters.common.quat import IDENTITY, Quat, Vec

_NS = 1e-9


class AhrsSettings(EstimatorSettings):
    """Settings every AHRS shares. Times in seconds."""

    sample_period_s: float = Field(0.005, gt=0.0)
    """Nominal gyro period: the first step, and any step whose timestamps cannot be used."""
    dt_from_timestamps: bool = True
    """Step length from consecutive gyro timestamps (False: always ``sample_period_s``)."""
    max_dt_s: float = Field(0.1, gt=0.0)
    """A gyro gap longer than this is not integrated over: the nominal period is used instead."""
    max_aux_age_s: float | None = Field(0.1, gt=0.0)
    """An accel or mag sample older than this (relative to the gyro sample) is not used."""


@dataclass(frozen=True, slots=True)
class ImuStep:
    """What one filter step gets: body NED axes, reference units."""

    gyro_rad_s: Vec
    accel_g: Vec | None
    """Gravity-positive accelerometer reading in g (level at rest: (0, 0, +1)), or None."""
    mag_ut: Vec | None
    dt_s: float


def _vec(v: Sequence[float]) -> Vec:
    x, y, z = (float(c) for c in v)
    return (x, y, z)


class AhrsEstimator(Estimator):
    """An attitude estimator stepped once per gyro sample. See the module docstring."""

    Settings: ClassVar[type[EstimatorSettings]] = AhrsSettings
    consumes: ClassVar[tuple[type, ...]] = (GyroSample, AccelSample, MagSample)
    uses_mag: ClassVar[bool] = True

    settings: AhrsSettings
    _q: Quat

    # ------------------------------------------------------------------ subclass hooks
    @abstractmethod
    def _reset_filter(self) -> None:
        """Initial filter state, including ``self._q``."""

    @abstractmethod
    def _step(self, step: ImuStep) -> dict[str, Any] | None:
        """Advance one gyro sample; return per-step diagnostics, or None for "no estimate yet"."""

    @abstractmethod
    def _filter_state(self) -> dict[str, Any]:
        """JSON-serialisable filter internals (the quaternion is saved by the base)."""

    @abstractmethod
    def _set_filter_state(self, state: dict[str, Any]) -> None:
        """Restore what ``_filter_state`` returned."""

    # ------------------------------------------------------------------ Estimator API
    def reset(self) -> None:
        self._accel_m_s2: Vec | None = None
        self._accel_t_ns: int | None = None
        self._mag_ut: Vec | None = None
        self._mag_t_ns: int | None = None
        self._last_gyro_t_ns: int | None = None
        self._counters: dict[str, Any] = {
            "steps": 0,
            "invalid": {c.value: 0 for c in (Channel.GYRO, Channel.ACCEL, Channel.MAG)},
            "dt_fallbacks": 0,
            "stale_accel": 0,
            "stale_mag": 0,
        }
        self._q = IDENTITY
        self._reset_filter()

    def process(self, item: Sample | Estimate) -> list[Estimate]:
        if not isinstance(item, (GyroSample, AccelSample, MagSample)):
            return []
        if not item.valid:
            self._counters["invalid"][item.channel.value] += 1
            return []
        if item.frame is not Frame.BODY_NED:
            raise ValueError(
                f"{self.instance}: {type(item).__name__} from {item.device!r} is in the "
                f"{item.frame.value!r} frame; AHRS estimators take body NED samples (apply the "
                "mount first)"
            )
        if isinstance(item, AccelSample):
            self._accel_m_s2, self._accel_t_ns = _vec(item.accel_m_s2), item.t_ns
            return []
        if isinstance(item, MagSample):
            if self.uses_mag:
                self._mag_ut, self._mag_t_ns = _vec(item.mag_ut), item.t_ns
            return []
        return self._on_gyro(item)

    def get_state(self) -> dict[str, Any]:
        return {
            "q": list(self._q),
            "last_gyro_t_ns": self._last_gyro_t_ns,
            "accel_m_s2": None if self._accel_m_s2 is None else list(self._accel_m_s2),
            "accel_t_ns": self._accel_t_ns,
            "mag_ut": None if self._mag_ut is None else list(self._mag_ut),
            "mag_t_ns": self._mag_t_ns,
            "counters": {**self._counters, "invalid": dict(self._counters["invalid"])},
            "filter": self._filter_state(),
        }

    def set_state(self, state: dict[str, Any]) -> None:
        q = state["q"]
        self._q = (float(q[0]), float(q[1]), float(q[2]), float(q[3]))
        self._last_gyro_t_ns = state["last_gyro_t_ns"]
        self._accel_m_s2 = None if state["accel_m_s2"] is None else _vec(state["accel_m_s2"])
        self._accel_t_ns = state["accel_t_ns"]
        self._mag_ut = None if state["mag_ut"] is None else _vec(state["mag_ut"])
        self._mag_t_ns = state["mag_t_ns"]
        counters = state["counters"]
        self._counters = {**counters, "invalid": dict(counters["invalid"])}
        self._set_filter_state(state["filter"])

    def diagnostics(self) -> dict[str, Any]:
        return {**self._counters, "invalid": dict(self._counters["invalid"])}

    # ------------------------------------------------------------------ Python API
    @property
    def quaternion(self) -> FloatArray:
        """Current body -> NED quaternion (w, x, y, z)."""
        return np.array(self._q)

    def update(
        self,
        gyro_rad_s: Sequence[float],
        accel_m_s2: Sequence[float] | None = None,
        mag_ut: Sequence[float] | None = None,
        dt_s: float | None = None,
    ) -> FloatArray | None:
        """One step from plain vectors (body NED; rad/s, specific force m/s^2, uT).

        ``dt_s`` defaults to ``sample_period_s``. Returns the new quaternion, or None while the
        filter has no attitude yet (imufilter before its first accelerometer sample).
        """
        accel_g = None if accel_m_s2 is None else gravity_positive_g(_vec(accel_m_s2))
        mag = _vec(mag_ut) if (mag_ut is not None and self.uses_mag) else None
        dt = self.settings.sample_period_s if dt_s is None else float(dt_s)
        self._counters["steps"] += 1
        if self._step(ImuStep(_vec(gyro_rad_s), accel_g, mag, dt)) is None:
            return None
        return np.array(self._q)

    # ------------------------------------------------------------------ internals
    def _on_gyro(self, gyro: GyroSample) -> list[Estimate]:
        dt = self._dt_for(gyro.t_ns)
        self._last_gyro_t_ns = gyro.t_ns
        accel = self._fresh(self._accel_m_s2, self._accel_t_ns, gyro.t_ns, "stale_accel")
        mag = self._fresh(self._mag_ut, self._mag_t_ns, gyro.t_ns, "stale_mag")
        accel_g = None if accel is None else gravity_positive_g(accel)
        self._counters["steps"] += 1
        diag = self._step(ImuStep(_vec(gyro.gyro_rad_s), accel_g, mag, dt))
        if diag is None:
            return []
        lin = None
        if accel is not None:
            a = linear_accel_ned_m_s2(self._q, accel)
            lin = (float(a[0]), float(a[1]), float(a[2]))
        return [
            AttitudeEstimate(
                t_ns=gyro.t_ns,
                source=self.instance,
                q_body_to_ned=self._q,
                linear_accel_ned_m_s2=lin,
                diagnostics={"dt_s": dt, **diag},
            )
        ]

    def _dt_for(self, t_ns: int) -> float:
        nominal = self.settings.sample_period_s
        if not self.settings.dt_from_timestamps or self._last_gyro_t_ns is None:
            return nominal
        dt = (t_ns - self._last_gyro_t_ns) * _NS
        if not (0.0 < dt <= self.settings.max_dt_s):
            self._counters["dt_fallbacks"] += 1
            return nominal
        return dt

    def _fresh(self, v: Vec | None, t_ns: int | None, now_ns: int, counter: str) -> Vec | None:
        if v is None or t_ns is None:
            return None
        max_age = self.settings.max_aux_age_s
        if max_age is not None and (now_ns - t_ns) * _NS > max_age:
            self._counters[counter] += 1
            return None
        return v
