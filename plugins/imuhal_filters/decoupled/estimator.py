"""The "decoupled" estimator: imuhal's own AHRS after VQF's method (see ``core.py``).

Live, it steps once per gyro sample through the shared AHRS machinery (aligned start,
full-scale rejection, turn compensation: ``common/ahrs.py``) and reports its rest detection,
magnetic disturbance detection and gyro bias on every estimate. ``offline: true`` (``imuhal
estimate`` / ``imuhal evaluate`` only: the whole recording known in advance) runs the filter
forwards and then backwards in time from where the forward pass ended, and averages the two
attitudes: each pass lags the truth by the
accelerometer filter's delay in opposite directions, and each pass's start-up (bias and field
reference not yet learnt) is covered by the other pass's converged end.
"""

from __future__ import annotations

import math
from typing import Any, ClassVar

import numpy as np
from pydantic import Field

from imuhal.core.frames import FloatArray
from imuhal_filters.common.ahrs import AhrsEstimator, AhrsSettings, ImuStep
from imuhal_filters.decoupled.core import DecoupledKernel, DecoupledParams


class DecoupledSettings(AhrsSettings):
    PRESETS: ClassVar[dict[str, dict[str, Any]]] = {
        # a glider or aircraft: sustained turns and pull-ups do not average out within
        # tau_acc_s; the soft gate keeps rc-flight under 10 deg (docs/estimators.md)
        "flight": {"accel_soft_gate_g": 0.02},
    }

    tau_acc_s: float = Field(3.0, gt=0.0)
    """Time constant (s) of the accelerometer low-pass in the almost-inertial frame: the
    inclination correction's speed (VQF's published default, 3 s)."""
    accel_soft_gate_g: float | None = Field(None, gt=0.0)
    """Share of each step the inclination filter advances by, 1 / (1 + (| |a| - 1 g | /
    width)^2) (common/gate.py): a reading away from 1 g is trusted less. None (default, VQF's
    choice): every reading in full. On BROAD (hand-held) 0.05 g made it worse (trials 05, 16,
    32: 4.44 against 1.18 deg 9-DOF total); in flight it is needed (``preset: flight``,
    0.02 g: `rc-flight` max 6.0 against 42.7 deg without): docs/estimators.md."""
    tau_mag_s: float = Field(9.0, gt=0.0)
    """Heading correction time constant (s) (VQF's published default, 9 s)."""
    rest_gyro_th_deg_s: float = Field(2.0, gt=0.0)
    """Rest: gyro within this (deg/s) of its 0.5 s low-pass (VQF: 2 deg/s)."""
    rest_acc_th_m_s2: float = Field(0.5, gt=0.0)
    """Rest: accelerometer within this (m/s^2) of its 0.5 s low-pass (VQF: 0.5 m/s^2)."""
    rest_min_s: float = Field(1.5, gt=0.0)
    """Rest is declared after this long still (s)."""
    bias_clip_deg_s: float = Field(2.0, gt=0.0)
    """Largest gyro bias estimated (deg/s); a steadier rotation is motion, not bias."""
    tau_bias_rest_s: float = Field(2.0, gt=0.0)
    """At rest the bias follows the low-passed gyro with this time constant (s)."""
    tau_bias_motion_s: float | None = Field(None, gt=0.0)
    """In motion the bias follows the correction rates with this time constant (s); None
    (default): bias only at rest (200 s made BROAD's fast translation worse: 2.77 against
    1.95 deg inclination on trial 16)."""
    mag_norm_th: float = Field(0.1, gt=0.0)
    """A field whose norm differs from the reference by more than this fraction is disturbed."""
    mag_dip_th_deg: float = Field(10.0, gt=0.0)
    """A field whose dip differs from the reference by more than this (deg) is disturbed."""
    mag_new_s: float = Field(20.0, gt=0.0)
    """A disturbed field that stays consistent this long (s) becomes the new reference."""
    use_mag: bool = True
    """Fuse the magnetometer (9-DOF); False: 6-DOF even when magnetometer samples arrive."""
    offline: bool = False
    """Forward-backward smoothing over a whole recording (estimate/evaluate only)."""

    def params(self) -> DecoupledParams:
        g = 9.80665
        return DecoupledParams(
            tau_acc_s=self.tau_acc_s, tau_mag_s=self.tau_mag_s,
            accel_soft_gate_g=self.accel_soft_gate_g,
            rest_gyro_th_rad_s=math.radians(self.rest_gyro_th_deg_s),
            rest_acc_th_g=self.rest_acc_th_m_s2 / g, rest_min_s=self.rest_min_s,
            bias_clip_rad_s=math.radians(self.bias_clip_deg_s),
            tau_bias_rest_s=self.tau_bias_rest_s, tau_bias_motion_s=self.tau_bias_motion_s,
            mag_norm_th=self.mag_norm_th, mag_dip_th_deg=self.mag_dip_th_deg,
            mag_new_s=self.mag_new_s)


class DecoupledEstimator(AhrsEstimator):
    """VQF's method in imuhal: inclination from gyro strapdown plus the accelerometer
    low-passed in an almost-inertial frame, rest-detected gyro bias, separate heading with
    magnetic disturbance rejection (6-DOF, or 9-DOF when magnetometer samples arrive)."""

    name: ClassVar[str] = "decoupled"
    description: ClassVar[str] = (
        "VQF-style AHRS: inertial-frame accel filtering, rest gyro bias, separate heading "
        "with magnetic disturbance rejection; offline forward-backward mode"
    )
    Settings: ClassVar[type[DecoupledSettings]] = DecoupledSettings  # type: ignore[assignment]
    settings: DecoupledSettings

    def _reset_filter(self) -> None:
        self._kernel = DecoupledKernel(self.settings.params())
        self._kernel.start(self._q)

    def _on_aligned(self) -> None:
        self._kernel.start(self._q, self._kernel.bias)

    def _step(self, step: ImuStep) -> dict[str, Any]:
        if self.settings.offline:
            raise ValueError(f"{self.instance}: offline: true needs the whole recording; run it "
                             "with `imuhal estimate` or `imuhal evaluate`, not live")
        k = self._kernel
        mag = step.mag_ut if self.settings.use_mag else None
        self._q = k.step(step.gyro_rad_s, step.accel_g, mag, step.dt_s)
        return {
            "rest_detected": k.rest,
            "mag_disturbed": k.mag_disturbed if mag is not None else None,
            "gyro_bias_rad_s": list(k.bias),
            "accel_used": step.accel_g is not None,
            "mag_used": mag is not None and not k.mag_disturbed,
        }

    def _filter_state(self) -> dict[str, Any]:
        k = self._kernel
        return {"q_gyro": list(k.q_gyro), "q_inc": list(k.q_inc), "delta_rad": k.delta_rad,
                "acc_i": None if k.acc_i is None else list(k.acc_i),
                "acc_filter": k._acc_filter.state, "bias": list(k.bias),
                "gyro_lp": None if k.gyro_lp is None else list(k.gyro_lp),
                "acc_lp": None if k.acc_lp is None else list(k.acc_lp), "rest_s": k.rest_s,
                "mag_ref": None if k.mag_ref is None else list(k.mag_ref),
                "mag_cand": None if k.mag_cand is None else list(k.mag_cand),
                "mag_cand_s": k.mag_cand_s, "mag_disturbed": k.mag_disturbed}

    def _set_filter_state(self, state: dict[str, Any]) -> None:
        k = self._kernel

        def tup(v: Any) -> Any:
            return None if v is None else tuple(float(c) for c in v)

        k.q_gyro, k.q_inc = tup(state["q_gyro"]), tup(state["q_inc"])
        k.delta_rad, k.acc_i, k.bias = float(state["delta_rad"]), tup(state["acc_i"]), \
            tup(state["bias"])
        k._acc_filter.state = None if state["acc_filter"] is None else [
            float(c) for c in state["acc_filter"]]
        k.gyro_lp, k.acc_lp, k.rest_s = tup(state["gyro_lp"]), tup(state["acc_lp"]), \
            float(state["rest_s"])
        k.mag_ref, k.mag_cand = tup(state["mag_ref"]), tup(state["mag_cand"])
        k.mag_cand_s, k.mag_disturbed = float(state["mag_cand_s"]), bool(state["mag_disturbed"])

    # ------------------------------------------------------------------ offline
    def _pass(self, gyro: FloatArray, accel: FloatArray, mag: FloatArray | None,
              sign: float, state: dict[str, Any] | None = None
              ) -> tuple[FloatArray, dict[str, Any]]:
        """One causal pass of a fresh copy of this estimator over the rows (``sign`` -1: rows
        already reversed, gyro negated: time reversal), from ``state`` when given. Returns
        the quaternions (NaN before alignment) and the final state."""
        live = type(self)({**self.settings.model_dump(), "offline": False})
        if state is not None:
            live.set_state(state)
        n = gyro.shape[0]
        out = np.full((n, 4), np.nan)
        dt = self.settings.sample_period_s
        for i in range(n):
            q = live.update(sign * gyro[i], accel[i],
                            None if mag is None else mag[i], dt)
            if q is not None:
                out[i] = q
        return out, live.get_state()

    @staticmethod
    def _reversed_state(state: dict[str, Any]) -> dict[str, Any]:
        """The end state of a forward pass as the start of the time-reversed one: the same
        attitude, accelerometer filter and field reference; the gyro (and so its bias and
        low-pass) negated."""
        f = dict(state["filter"])
        f["bias"] = [-c for c in f["bias"]]
        if f["gyro_lp"] is not None:
            f["gyro_lp"] = [-c for c in f["gyro_lp"]]
        return {**state, "filter": f}

    def smooth(self, gyro_rad_s: FloatArray, accel_m_s2: FloatArray,
               mag_ut: FloatArray | None) -> FloatArray:
        """Forward-backward smoothing over a whole recording: (N, 3) body NED arrays (rad/s,
        specific force m/s^2, uT), one row per gyro sample at ``sample_period_s``; returns
        the (N, 4) body -> NED quaternions, the normalised mean of the two passes."""
        mag = mag_ut if self.settings.use_mag else None
        fwd, end = self._pass(gyro_rad_s, accel_m_s2, mag, 1.0)
        rev = slice(None, None, -1)
        # the backward pass starts where the forward one ended (bias and field reference
        # learnt), so neither pass's start-up is left uncovered
        bwd = self._pass(gyro_rad_s[rev], accel_m_s2[rev], None if mag is None else mag[rev],
                         -1.0, self._reversed_state(end))[0][rev]
        bwd = np.where(np.isnan(bwd), fwd, bwd)
        fwd = np.where(np.isnan(fwd), bwd, fwd)
        sign = np.where(np.sum(fwd * bwd, axis=1) < 0.0, -1.0, 1.0)[:, None]
        mean = fwd + sign * bwd
        return mean / np.linalg.norm(mean, axis=1, keepdims=True)
