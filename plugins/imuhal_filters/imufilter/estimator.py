"""The "imufilter" estimator: RCmags imuFilter v1.6.3 (6-DOF) with its velocity estimate.

The attitude is set up from the first accelerometer sample (tilt from gravity, yaw 0): until
then the estimator emits nothing. Each later gyro sample runs one update: the rotated
accelerometer is compared with (0, 0, 1) g; its squared deviation feeds a Kalman-like variance
whose gain (1 inside the ``sd_acc_g`` band, falling outside it) scales the correction, and
``gain`` (the library's ALPHA) sets how fast the correction acts. With no fresh accel sample
the step integrates the gyro alone. Heading is relative (no magnetometer); ``rotate_heading``
turns it about the vertical, e.g. to align it with an external heading.

When ``velocity`` is on, each step also runs the library's velocity filter (see
``velocity.py``); the estimate is in the diagnostics as ``velocity_ned_m_s``.

By default (not in the presets) the board's rests are detected (``common/rest.py``), as in
madgwick and mahony: there the correction runs at gain 1 and the gyro bias is learned
(``rest_gyro_bias_rad_s``), subtracted from every gyro sample the filter integrates. The
library has no bias estimate: its correction holds a still board tilted by the bias over
``gain`` (1 deg/s: 2 deg, for good), and a board without stored gyro offsets drifts in flight.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any, ClassVar, Literal

import numpy as np
from pydantic import Field

from imuhal.core.atmosphere import STANDARD_GRAVITY_M_S2
from imuhal.core.frames import FloatArray
from imuhal.core.gaps import StreamGap
from imuhal.core.samples import AccelSample, AirspeedSample, GyroSample, VelocitySample
from imuhal_filters.common.ahrs import (
    NO_VECTOR,
    TO_G,
    AhrsEstimator,
    AhrsSettings,
    ImuStep,
    _linear_accel_ned,
)
from imuhal_filters.common.fast import Kernel
from imuhal_filters.common.gate import gravity_positive_g, specific_force_m_s2
from imuhal_filters.common.quat import Vec, to_global, to_local
from imuhal_filters.common.rest import RestSettings
from imuhal_filters.imufilter.core import (
    axis_unit_vectors,
    gyro_step,
    imufilter_step,
    rotate_heading,
    setup_quaternion,
)
from imuhal_filters.imufilter.fast import imufilter_rows, imufilter_sample, pack_state
from imuhal_filters.imufilter.velocity import ZERO, VelocityState, velocity_step


class ImuFilterSettings(AhrsSettings, RestSettings):
    PRESETS: ClassVar[dict[str, dict[str, Any]]] = {
        "reference": {"turn_compensation": False, "rest_detection": False},
        "seed": {"turn_compensation": False, "rest_detection": False},
    }

    initial_attitude: Literal["first_sample"] = "first_sample"
    """The library itself starts from the first accelerometer sample (tilt, yaw 0)."""
    gain: float = Field(0.5, ge=0.0)
    """The library's ALPHA (DEFAULT_GAIN): correction rate; smaller = smoother, slower."""
    sd_acc_g: float = Field(0.2, gt=0.0)
    """Accelerometer band (DEFAULT_SD_ACC, g): deviations inside it count as "at rest"."""
    velocity: bool = True
    """Also run the velocity filter (accIntegral)."""
    sd_vel_g_s: float = Field(0.1, gt=0.0)
    """Velocity band (DEFAULT_SD_VEL, g*s = 9.80665 m/s per unit)."""


class ImuFilterEstimator(AhrsEstimator):
    """imuFilter-style 6-DOF attitude filter with a Kalman-like accelerometer band check."""

    name: ClassVar[str] = "imufilter"
    description: ClassVar[str] = (
        "RCmags imuFilter: 6-DOF quaternion filter with a Kalman-like accel band, and velocity"
    )
    Settings: ClassVar[type[ImuFilterSettings]] = ImuFilterSettings
    # StreamGap: a gyro step over frames the pipeline counted lost is integrated over its
    # true interval up to max_gap_s, as in every AHRS (imuhal_filters.common.ahrs)
    consumes: ClassVar[tuple[type, ...]] = (GyroSample, AccelSample, VelocitySample,
                                            AirspeedSample, StreamGap)
    uses_mag: ClassVar[bool] = False
    settings: ImuFilterSettings

    def _reset_filter(self) -> None:
        self._initialized = False
        self._var = 0.0
        self._gain = 1.0
        self._vel = VelocityState()
        self._vel_target: Vec = ZERO
        s = self.settings
        self._velocity_on = s.velocity
        self._alpha, self._sd_acc_g = float(s.gain), float(s.sd_acc_g)
        # velocity_step's constants, computed as it computes them
        sd_acc_m_s2 = s.sd_acc_g * STANDARD_GRAVITY_M_S2
        sd_vel_m_s = s.sd_vel_g_s * STANDARD_GRAVITY_M_S2
        self._var_a = sd_acc_m_s2 * sd_acc_m_s2
        self._var_comb = self._var_a * sd_vel_m_s * sd_vel_m_s
        # the compiled per-sample step where it pays (the AOT extension; common/fast.py)
        self._sample_kernel = imufilter_sample.per_sample()

    def _compiled_step(self, gyro: Vec, accel_m_s2: Vec | None, mag: Vec | None, dt: float,
                       measured_m_s2: Vec | None) -> dict[str, Any] | None:
        """``_step`` in the compiled per-sample kernel once set up (the set-up step stays in
        Python): the same floats (tests compare them)."""
        if not self._initialized:
            diag = self._step(ImuStep(gyro, None if accel_m_s2 is None else
                                      gravity_positive_g(accel_m_s2), mag, dt))
            self._linear_ned = (None if measured_m_s2 is None else
                                _linear_accel_ned(self._q, measured_m_s2))
            return None if diag is None else {
                "dt_s": dt, "turn_compensation": self._kinematics.source, **diag}
        gx, gy, gz = gyro
        if accel_m_s2 is None:
            have_a, ax, ay, az = False, 0.0, 0.0, 0.0
        else:
            have_a = True
            ax, ay, az = (accel_m_s2[0] * TO_G, accel_m_s2[1] * TO_G, accel_m_s2[2] * TO_G)
        vel = self._vel
        (w, x, y, z, var, gain, v0, v1, v2, m0, m1, m2, l0, l1, l2, var_vel, var_acc, lx, ly,
         lz) = self._sample_kernel(
            *self._q, self._var, self._gain, gx, gy, gz, have_a, ax, ay, az, dt, self._alpha,
            self._sd_acc_g, self._velocity_on, self._var_a, self._var_comb, *vel.velocity,
            *vel.accel_mean, *vel.accel_last, vel.var_vel, vel.var_acc, *self._vel_target,
            self._at_rest, *(NO_VECTOR if measured_m_s2 is None else measured_m_s2))
        self._q, self._var, self._gain = (w, x, y, z), var, gain
        self._linear_ned = (lx, ly, lz)
        if self._velocity_on and have_a:
            self._vel = VelocityState((v0, v1, v2), (m0, m1, m2), (l0, l1, l2), var_vel,
                                      var_acc)
        d: dict[str, Any] = {"dt_s": dt, "turn_compensation": self._kinematics.source,
                             "accel_used": have_a, "accel_gain": gain, "accel_variance_g2": var,
                             "at_rest": self._at_rest,
                             "rest_gyro_bias_rad_s": self.rest_gyro_bias_rad_s}
        if self._velocity_on:
            d["velocity_ned_m_s"] = self._vel.velocity
        return d

    def _step(self, step: ImuStep) -> dict[str, Any] | None:
        accel = step.accel_g
        if not self._initialized:
            if accel is None:
                return None  # no attitude until gravity has been seen once
            self._q = setup_quaternion(accel)
            self._var, self._gain, self._initialized = 0.0, 1.0, True
            self._vel = VelocityState()
            return self._diag(accel_used=True, setup=True)
        if accel is None:
            self._q = gyro_step(self._q, step.gyro_rad_s, step.dt_s)
            return self._diag(accel_used=False)
        self._q, self._var, self._gain = imufilter_step(
            self._q, self._var, step.gyro_rad_s, accel, step.dt_s, self.settings.gain,
            self.settings.sd_acc_g, at_rest=self._at_rest,
        )
        if self.settings.velocity:
            self._vel = velocity_step(
                self._vel, self._q, step.gyro_rad_s, specific_force_m_s2(accel), step.dt_s,
                self.settings.sd_acc_g * STANDARD_GRAVITY_M_S2,
                self.settings.sd_vel_g_s * STANDARD_GRAVITY_M_S2,
                self._vel_target,
            )
        return self._diag(accel_used=True)

    def _diag(self, *, accel_used: bool, setup: bool = False) -> dict[str, Any]:
        d: dict[str, Any] = {
            "accel_used": accel_used,
            "accel_gain": self._gain,
            "accel_variance_g2": self._var,
            "at_rest": self._at_rest,
            "rest_gyro_bias_rad_s": self.rest_gyro_bias_rad_s,
        }
        if setup:
            d["setup"] = True
        if self.settings.velocity:
            d["velocity_ned_m_s"] = self._vel.velocity
        return d

    # ------------------------------------------------------------------ compiled kernel
    _compiled_kernel: ClassVar[Kernel | None] = imufilter_rows
    _kernel_diag_width: ClassVar[int] = 10

    def _kernel_ready(self) -> bool:
        return self._initialized

    def _run_kernel(self, gyro: FloatArray, accel: FloatArray, mag: FloatArray,
                    dts: FloatArray, out: FloatArray, diag: FloatArray) -> bool:
        """The rows in the compiled kernel (``fast`` extra); see ``AhrsEstimator._run_kernel``."""
        s = self.settings
        state = pack_state(self._q, self._var, self._gain, self._vel, self._vel_target)
        rest, params = self._rest_arrays()
        turn_sum = self._rows_kernel()(
            state, gyro, accel, dts, float(s.gain), float(s.sd_acc_g), s.velocity,
            s.sd_acc_g * STANDARD_GRAVITY_M_S2, s.sd_vel_g_s * STANDARD_GRAVITY_M_S2,
            s.turn_compensation, self._kinematics.turn_sum, out, diag, rest, params)
        v = state.tolist()
        self._var, self._gain = v[4], v[5]
        self._vel = VelocityState((v[6], v[7], v[8]), (v[9], v[10], v[11]),
                                  (v[12], v[13], v[14]), v[15], v[16])
        self._kernel_finished(state[:4], len(gyro), 0, turn_sum, rest)
        return True

    def _block_kernel(self) -> bool:
        return True

    def _kernel_row_diagnostics(self, dts: FloatArray, diag: FloatArray, source: str
                                ) -> list[dict[str, Any]]:
        rows = diag.tolist()
        if self.settings.velocity:
            return [{"dt_s": dt, "turn_compensation": source, "accel_used": a == 1.0,
                     "accel_gain": g, "accel_variance_g2": v, "at_rest": r == 1.0,
                     "rest_gyro_bias_rad_s": (bx, by, bz), "velocity_ned_m_s": (x, y, z)}
                    for dt, (a, g, v, x, y, z, r, bx, by, bz) in zip(dts.tolist(), rows,
                                                                     strict=True)]
        return [{"dt_s": dt, "turn_compensation": source, "accel_used": a == 1.0,
                 "accel_gain": g, "accel_variance_g2": v, "at_rest": r == 1.0,
                 "rest_gyro_bias_rad_s": (bx, by, bz)}
                for dt, (a, g, v, _, _, _, r, bx, by, bz) in zip(dts.tolist(), rows,
                                                                 strict=True)]

    def _kernel_diagnostics(self, diag: FloatArray) -> dict[str, Any]:
        cols: dict[str, Any] = {"accel_used": diag[:, 0].astype(np.int64),
                                "accel_gain": diag[:, 1], "accel_variance_g2": diag[:, 2],
                                "at_rest": diag[:, 6].astype(np.int64),
                                **{f"rest_gyro_bias_rad_s_{i}": diag[:, 7 + i]
                                   for i in range(3)}}
        if self.settings.velocity:
            cols.update({f"velocity_ned_m_s_{i}": diag[:, 3 + i] for i in range(3)})
        return cols

    # ------------------------------------------------------------------ library functions
    @property
    def initialized(self) -> bool:
        return self._initialized

    @property
    def velocity_ned_m_s(self) -> FloatArray:
        return np.array(self._vel.velocity)

    def set_velocity_target(self, target_ned_m_s: Sequence[float]) -> None:
        """The velocity the filter relaxes to while accelerations are small (default 0)."""
        x, y, z = (float(c) for c in target_ned_m_s)
        self._vel_target = (x, y, z)

    def rotate_heading(self, angle_rad: float, *, small_angle: bool = False) -> None:
        """Turn the attitude about the vertical by ``angle_rad`` (yaw increases)."""
        self._q = rotate_heading(self._q, angle_rad, small_angle=small_angle)

    def to_global(self, v_body: Sequence[float]) -> FloatArray:
        """A body-frame vector in NED."""
        return np.array(to_global(self._q, (float(v_body[0]), float(v_body[1]),
                                            float(v_body[2]))))

    def to_local(self, v_ned: Sequence[float]) -> FloatArray:
        """A NED vector in body axes."""
        return np.array(to_local(self._q, (float(v_ned[0]), float(v_ned[1]), float(v_ned[2]))))

    def axis(self, which: Literal["x", "y", "z"], *, in_global: bool = True) -> FloatArray:
        """Unit vector of a body axis in NED (``in_global``) or of a NED axis in the body."""
        return np.array(axis_unit_vectors(self._q, in_global=in_global)["xyz".index(which)])

    # ------------------------------------------------------------------ state
    def _filter_state(self) -> dict[str, Any]:
        return {
            "initialized": self._initialized,
            "var": self._var,
            "gain": self._gain,
            "velocity": self._vel.to_dict(),
            "velocity_target": list(self._vel_target),
        }

    def _set_filter_state(self, state: dict[str, Any]) -> None:
        self._initialized = bool(state["initialized"])
        self._var = float(state["var"])
        self._gain = float(state["gain"])
        self._vel = VelocityState.from_dict(state["velocity"])
        self.set_velocity_target(state["velocity_target"])
