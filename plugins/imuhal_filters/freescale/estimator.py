"""``freescale-9dof`` and ``freescale-6dof``: the Freescale Kalman filters as imuhal estimators.

Samples arrive in project units and body NED axes (GyroSample rad/s, AccelSample specific
force m/s^2, MagSample calibrated uT). At the boundary they become the reference's units and
the sensor axes/sign of the configured coordinate system (``coords``). Every valid gyro
sample is one fast tick, integrated over 1 / sensor_rate_hz (the reference assumes a steady
rate; timestamps only stamp the output). After ``oversample_ratio`` gyro samples a Kalman
step runs on them and on the newest accelerometer (and magnetometer) sample — waiting, if
needed, for one stamped at or after the window's last gyro sample, but no longer than until
the next gyro sample arrives; then it reuses the last reading (as the reference does; counted
as stale) or, with none yet, drops the window (counted). Each valid step emits an
AttitudeEstimate (body -> NED) stamped with the window's last gyro sample.

Every gyro sample is also a tick of the rest detector (``rest.WindowRest``, with the newest
accelerometer reading); a window it found still at every tick is fused as a rest
(``kalman.FreescaleKalman.step``'s ``at_rest``; diagnostics ``at_rest``, counter
``windows_at_rest``).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any, ClassVar

import numpy as np

from imuhal.core.atmosphere import STANDARD_GRAVITY_M_S2
from imuhal.core.frames import FloatArray
from imuhal.core.gaps import StreamGap
from imuhal.core.quantities import Quantity
from imuhal.core.samples import (
    AccelSample,
    AirspeedSample,
    Frame,
    GyroSample,
    MagSample,
    Sample,
    VelocitySample,
)
from imuhal.core.streams import StreamSpec
from imuhal.estimation.base import Estimator, EstimatorSettings
from imuhal.estimation.gravity import linear_accel_ned_m_s2
from imuhal.estimation.outputs import AttitudeEstimate, Estimate
from imuhal_filters.common.fast_ahrs import TO_G
from imuhal_filters.common.gaps import CountedGaps
from imuhal_filters.common.limits import bound_settings, within_full_scale
from imuhal_filters.common.quat import Vec
from imuhal_filters.common.turn import KinematicAcceleration
from imuhal_filters.freescale.coords import (
    SignedAxes,
    quat_body_to_ned,
    sensor_axes,
    to_sensor_vector,
)
from imuhal_filters.freescale.kalman import FreescaleKalman, KalmanStep
from imuhal_filters.freescale.rest import WindowRest
from imuhal_filters.freescale.settings import (
    Freescale6DofSettings,
    Freescale9DofSettings,
    FreescaleCommonSettings,
)

_COUNTERS = ("gyro_samples", "accel_samples", "mag_samples", "kalman_steps",
             "skipped_invalid", "skipped_not_body_frame", "windows_without_accel_or_mag",
             "windows_with_stale_accel_or_mag", "beyond_full_scale", "gyro_ticks_over_gaps",
             "restarts_after_gap", "windows_at_rest")
REST_ACCEL_MAX_AGE_S = 0.1
"""The rest detector takes the newest accelerometer reading while it is at most this old (s;
the AHRS family's ``max_aux_age_s``): older, there is none, and the stillness breaks."""


class _Latest:
    """The newest sample of one sensor (reference units) and the sum over the window."""

    # plain float tuples per sample (a numpy array per 3-vector costs more than it saves);
    # arrays only once per Kalman step, in take()
    def __init__(self) -> None:
        self.value: Vec | None = None
        self.t_ns: int | None = None
        self.sum: Vec = (0.0, 0.0, 0.0)
        self.count = 0

    def add(self, t_ns: int, v: Vec) -> None:
        self.value, self.t_ns = v, t_ns
        s = self.sum
        self.sum = (s[0] + v[0], s[1] + v[1], s[2] + v[2])
        self.count += 1

    def take(self, average: bool) -> FloatArray | None:
        """The value a Kalman step fuses; restarts the window sum."""
        out = None if self.value is None else np.array(self.value)
        if average and self.count:
            out = np.array(self.sum) / self.count
        self.sum, self.count = (0.0, 0.0, 0.0), 0
        return out

    def as_dict(self) -> dict[str, Any]:
        return {"value": None if self.value is None else list(self.value), "t_ns": self.t_ns,
                "sum": list(self.sum), "count": self.count}

    def load_dict(self, d: dict[str, Any]) -> None:
        self.value = None if d["value"] is None else _floats(d["value"])
        self.t_ns = None if d["t_ns"] is None else int(d["t_ns"])
        self.sum = _floats(d["sum"])
        self.count = int(d["count"])


def _floats(v: Any) -> Vec:
    x, y, z = v
    return (float(x), float(y), float(z))


def _permute(v: Vec, axes: SignedAxes) -> Vec:
    (i, a), (j, b), (k, c) = axes
    return (a * v[i], b * v[j], c * v[k])


class _FreescaleEstimator(Estimator):
    """The oversampling front end shared by the 6DOF and 9DOF filters."""

    use_mag: ClassVar[bool]
    settings: FreescaleCommonSettings

    def reset(self) -> None:
        self._kf = FreescaleKalman(self.settings, use_mag=self.use_mag)
        self._gyro: list[Vec] = []
        self._gyro_t_ns: int | None = None
        self._accel = _Latest()
        self._force = _Latest()  # the raw specific force, for the published linear accel
        self._mag = _Latest()
        self._pending = False
        self._rest = WindowRest(self.settings)
        self._pending_at_rest = False
        """The rest verdict of the window waiting for its Kalman step."""
        self._last_step: KalmanStep | None = None
        self._counts = dict.fromkeys(_COUNTERS, 0)
        # an IMU's streams come in the same reads: a loss counted on its accelerometer (the
        # faster channel of some chips) lost the same gyro frames
        self._gaps = CountedGaps((Quantity.GYRO, Quantity.ACCEL))
        self._kinematics = KinematicAcceleration(self.settings)
        self._kinematic_body_m_s2: Vec = (0.0, 0.0, 0.0)
        cs = self.settings.coordinate_system
        self._axes = sensor_axes(cs)
        self._accel_axes = sensor_axes(cs, specific_force=True)

    # -- Estimator interface ----------------------------------------------------------------

    def bind(self, streams: Sequence[StreamSpec]) -> None:
        """``sensor_rate_hz`` (every gyro sample is integrated over 1 / it, whatever its
        time stamps) and the limits from the gyro and accelerometer streams, unless given
        by hand; a hand setting that contradicts its stream raises StreamContradiction."""
        bound = bound_settings(self, streams, rate_key="sensor_rate_hz")
        if bound is not self.settings:
            self.settings = bound
            self.reset()

    def process(self, item: Sample | Estimate) -> list[Estimate]:
        if not isinstance(item, self.consumes):
            return []
        if isinstance(item, StreamGap):
            self._gaps.note(item)
            return []
        if isinstance(item, VelocitySample | AirspeedSample):
            self._on_speed(item)
            return []
        assert isinstance(item, GyroSample | AccelSample | MagSample)
        vec = _floats(item.vector)
        if not item.valid or not (math.isfinite(vec[0]) and math.isfinite(vec[1])
                                  and math.isfinite(vec[2])):
            self._counts["skipped_invalid"] += 1
            return []
        if item.frame is not Frame.BODY_NED:
            self._counts["skipped_not_body_frame"] += 1
            return []
        if not self._within_full_scale(item):
            self._counts["beyond_full_scale"] += 1
            return []
        out: list[Estimate] = []
        if isinstance(item, GyroSample):
            out += self._on_gyro(item.t_ns, vec)
        elif isinstance(item, AccelSample):
            self._counts["accel_samples"] += 1
            k = self._kinematic_body_m_s2  # turn compensation (zero without a source)
            g = STANDARD_GRAVITY_M_S2
            self._force.add(item.t_ns, vec)
            force_g = ((vec[0] - k[0]) / g, (vec[1] - k[1]) / g, (vec[2] - k[2]) / g)
            self._accel.add(item.t_ns, _permute(force_g, self._accel_axes))
        else:
            self._counts["mag_samples"] += 1
            self._mag.add(item.t_ns, _permute(vec, self._axes))
        if self._pending and self._caught_up():
            out += self._run_step()
        return out

    def _on_gyro(self, t_ns: int, vec: Vec) -> list[Estimate]:
        """One gyro sample (body NED, rad/s) at ``t_ns``, after the frames counted lost just
        before it: each a fast tick at this sample's rate (the AHRS family's "integrate over
        the true interval with the rate after it"), or a restart beyond ``max_gap_s``."""
        out: list[Estimate] = []
        deg = _permute((math.degrees(vec[0]), math.degrees(vec[1]), math.degrees(vec[2])),
                       self._axes)
        ticks = [t_ns]
        last = self._gyro_t_ns
        if last is not None and self._gaps.explained(t_ns):
            span_ns = t_ns - last
            if span_ns > self.settings.max_gap_s * 1e9:
                self._restart()
            else:
                lost = max(0, round(span_ns * 1e-9 * self.settings.sensor_rate_hz) - 1)
                self._counts["gyro_ticks_over_gaps"] += lost
                ticks = [last + span_ns * (k + 1) // (lost + 1) for k in range(lost + 1)]
        for tick_ns in ticks:
            if self._pending:  # the window's accel/mag never caught up: use what there is
                out += self._run_step()
            if tick_ns == t_ns:
                self._rest.tick(vec, self._rest_accel_g(t_ns), self.settings.fast_dt_s)
            else:
                self._rest.unmeasured_tick()
            self._gyro.append(deg)
            self._gyro_t_ns = tick_ns
            if len(self._gyro) == self.settings.oversample_ratio:
                self._pending = True
                self._pending_at_rest = self._rest.take_window()
        self._counts["gyro_samples"] += 1
        self._kinematic_body_m_s2 = self._kinematics.step(t_ns, vec)
        return out

    def _rest_accel_g(self, t_ns: int) -> Vec | None:
        """The newest specific force as the rest detector takes it (gravity-positive g, body
        NED), or None when there is none within REST_ACCEL_MAX_AGE_S of ``t_ns``."""
        f, f_t_ns = self._force.value, self._force.t_ns
        if f is None or f_t_ns is None or (t_ns - f_t_ns) * 1e-9 > REST_ACCEL_MAX_AGE_S:
            return None
        return (f[0] * TO_G, f[1] * TO_G, f[2] * TO_G)

    def _restart(self) -> None:
        """A counted loss longer than ``max_gap_s``: the filter starts again (and locks to the
        next window), its counters going on."""
        counts = self._counts
        kinematics = self._kinematics
        self.reset()
        self._counts, self._kinematics = counts, kinematics
        counts["restarts_after_gap"] += 1

    def _on_speed(self, item: VelocitySample | AirspeedSample) -> None:
        if not item.valid:
            self._counts["skipped_invalid"] += 1
        elif isinstance(item, VelocitySample):
            if within_full_scale(item.velocity_ned_m_s, None):
                self._kinematics.on_velocity(item)
        elif within_full_scale((item.airspeed_m_s,), None):
            self._kinematics.on_airspeed(item)

    def _within_full_scale(self, item: GyroSample | AccelSample | MagSample) -> bool:
        """A gyro or accel value beyond the physical full scale is never fused (counted)."""
        s = self.settings
        if isinstance(item, GyroSample):
            return within_full_scale(item.gyro_rad_s, s.gyro_full_scale_rad_s)
        if isinstance(item, AccelSample):
            return within_full_scale(item.accel_m_s2, s.accel_full_scale_m_s2)
        return True

    def _caught_up(self) -> bool:
        """The accel (and mag) samples of the tick that closed the gyro window have arrived."""
        t = self._gyro_t_ns
        sensors = (self._accel, self._mag) if self.use_mag else (self._accel,)
        return all(s.t_ns is not None and t is not None and s.t_ns >= t for s in sensors)

    def _run_step(self) -> list[Estimate]:
        self._pending = False
        gyro = np.array(self._gyro)
        self._gyro = []
        # the lock that replaces the reference's init-only step uses the window's mean: a
        # single sample's noise would stay in the heading for seconds
        average = self.settings.accel_mag_input == "average" or not (
            self._kf.locked or self.settings.initialise_on_first_step)
        sensors = (self._accel, self._mag) if self.use_mag else (self._accel,)
        stale = any(s.count == 0 for s in sensors)
        accel = self._accel.take(average)
        force = self._force.take(average)
        mag = self._mag.take(average) if self.use_mag else None
        if accel is None or (self.use_mag and mag is None):
            self._counts["windows_without_accel_or_mag"] += 1
            return []
        if stale:  # the reference, too, fuses the last reading it has; say so
            self._counts["windows_with_stale_accel_or_mag"] += 1
        at_rest, self._pending_at_rest = self._pending_at_rest, False
        step = self._kf.step(accel, gyro, mag, at_rest=at_rest)
        self._counts["kalman_steps"] += 1
        self._counts["windows_at_rest"] += at_rest
        self._last_step = step
        if not step.valid:
            return []
        assert force is not None  # taken with accel
        return [self._estimate(step, force)]

    def _estimate(self, step: KalmanStep, force_body_m_s2: FloatArray) -> AttitudeEstimate:
        """The estimate; its gravity-compensated acceleration comes from the raw specific
        force (body NED, m/s^2) the step fused, as every AHRS publishes it: the turn
        compensation's estimate is for the tilt correction only (its errors, e.g. a
        pendulum's pitch rate times the airspeed, would be false vertical acceleration)."""
        cs = self.settings.coordinate_system
        q = quat_body_to_ned(cs, step.q_sensor_to_global)
        lin = linear_accel_ned_m_s2(q, force_body_m_s2)
        assert self._gyro_t_ns is not None
        return AttitudeEstimate(
            t_ns=self._gyro_t_ns,
            source=self.instance,
            q_body_to_ned=(float(q[0]), float(q[1]), float(q[2]), float(q[3])),
            linear_accel_ned_m_s2=(float(lin[0]), float(lin[1]), float(lin[2])),
            diagnostics=self._step_diagnostics(step),
        )

    def _step_diagnostics(self, step: KalmanStep) -> dict[str, Any]:
        cs = self.settings.coordinate_system
        offset_body_dps = to_sensor_vector(cs, step.gyro_offset_dps)  # the swap is involutory
        diag: dict[str, Any] = {
            "gyro_offset_rad_s": tuple(math.radians(float(v)) for v in offset_body_dps),
            "gyro_offset_dps": tuple(float(v) for v in offset_body_dps),
            "euler_deg": dict(step.euler_deg),
            "coordinate_system": cs.value,
            "at_rest": self._rest.at_rest,
            **self._counts,
        }
        if self.use_mag:
            diag["inclination_deg"] = step.inclination_deg
            diag["mag_jamming"] = step.mag_jamming
        return diag

    def get_state(self) -> dict[str, Any]:
        return {
            "kf": self._kf.as_dict(),
            "gyro": [list(g) for g in self._gyro],
            "gyro_t_ns": self._gyro_t_ns,
            "accel": self._accel.as_dict(),
            "force": self._force.as_dict(),
            "mag": self._mag.as_dict(),
            "pending": self._pending,
            "pending_at_rest": self._pending_at_rest,
            "rest": self._rest.as_dict(),
            "counts": dict(self._counts),
            "kinematics": self._kinematics.as_dict(),
            "kinematic_body_m_s2": list(self._kinematic_body_m_s2),
        }

    def set_state(self, state: dict[str, Any]) -> None:
        self._kf.load_dict(state["kf"])
        self._gyro = [_floats(g) for g in state["gyro"]]
        t = state["gyro_t_ns"]
        self._gyro_t_ns = None if t is None else int(t)
        self._accel.load_dict(state["accel"])
        if "force" in state:
            self._force.load_dict(state["force"])
        self._mag.load_dict(state["mag"])
        self._pending = bool(state["pending"])
        self._pending_at_rest = bool(state.get("pending_at_rest", False))
        if "rest" in state:
            self._rest.load_dict(state["rest"])
        self._counts = {k: int(state["counts"].get(k, 0)) for k in _COUNTERS}
        if "kinematics" in state:
            self._kinematics.load_dict(state["kinematics"])
            self._kinematic_body_m_s2 = _floats(state["kinematic_body_m_s2"])

    def diagnostics(self) -> dict[str, Any]:
        out: dict[str, Any] = dict(self._counts)
        out["rest"] = {"detection": self._rest.on, "at_rest": self._rest.at_rest,
                       "gyro_bias_rad_s": self._rest.bias_rad_s}
        if self._last_step is not None and self._last_step.valid:
            out.update(self._step_diagnostics(self._last_step))
        return out


class Freescale9DofEstimator(_FreescaleEstimator):
    """Accelerometer + magnetometer + gyro Kalman filter (fRun_9DOF_GBY_KALMAN, build 422).

    Needs a calibrated magnetometer (hard/soft iron removed). Diagnostics per step: gyro
    offset estimate (rad/s and deg/s, body NED), tracked geomagnetic inclination (deg),
    magnetic jamming flag, the coordinate system's own Euler angles and sample counters.
    """

    name: ClassVar[str] = "freescale-9dof"
    description: ClassVar[str] = (
        "Freescale/NXP 9DOF indirect Kalman (gyro offset, linear acceleration, magnetic "
        "disturbance, jamming detection, inclination tracking)"
    )
    Settings: ClassVar[type[EstimatorSettings]] = Freescale9DofSettings
    consumes: ClassVar[tuple[type, ...]] = (GyroSample, AccelSample, MagSample,
                                            VelocitySample, AirspeedSample, StreamGap)
    use_mag: ClassVar[bool] = True


class Freescale6DofEstimator(_FreescaleEstimator):
    """Accelerometer + gyro Kalman filter (fRun_6DOF_GY_KALMAN, build 422).

    Yaw is unobservable: it starts at zero (the board's heading at start-up) and then
    follows the offset-corrected gyro. Diagnostics: gyro offset estimate, Euler angles and
    sample counters.
    """

    name: ClassVar[str] = "freescale-6dof"
    description: ClassVar[str] = (
        "Freescale/NXP 6DOF indirect Kalman (accelerometer + gyro, gyro offset and linear "
        "acceleration)"
    )
    Settings: ClassVar[type[EstimatorSettings]] = Freescale6DofSettings
    consumes: ClassVar[tuple[type, ...]] = (GyroSample, AccelSample, VelocitySample,
                                            AirspeedSample, StreamGap)
    use_mag: ClassVar[bool] = False
