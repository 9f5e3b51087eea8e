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

from imuhal.core.atmosphere import STANDARD_GRAVITY_M_S2
from imuhal.core.blocks import Block
from imuhal.core.frames import FloatArray
from imuhal.estimation.base import Estimator
from imuhal.estimation.outputs import AttitudeBlock, Estimate
from imuhal_filters.common.ahrs import AhrsEstimator, AhrsSettings, ImuStep
from imuhal_filters.common.alignment import aligned_quaternion
from imuhal_filters.common.fast import c_array
from imuhal_filters.common.gate import gravity_positive_g
from imuhal_filters.common.innovation import ManoeuvreParams
from imuhal_filters.common.quat import IDENTITY, Quat, Vec
from imuhal_filters.decoupled.bias import BiasParams
from imuhal_filters.decoupled.core import DecoupledKernel, DecoupledParams
from imuhal_filters.decoupled.fast import decoupled_block, decoupled_rows, decoupled_sample
from imuhal_filters.decoupled.packed import covers, grown, pack, params_array, unpack
from imuhal_filters.decoupled.smoother import (
    PassRecord,
    apply_heading,
    clean_field,
    field_weights,
    fused_bias,
    heading,
    inclination,
    rotate_rows,
    strapdown,
    zero_phase,
)


def _information(cov: FloatArray) -> FloatArray:
    """(n, 3, 3) inverses of (n, 9) covariances: ``bias.inv3`` row by row, elementwise (the
    same IEEE operations, so the same floats as ``GyroBiasKalman.information``)."""
    a, b, c, d, e, f, g, h, i = (cov[:, j] for j in range(9))
    A, B, C = e * i - f * h, f * g - d * i, d * h - e * g
    r = 1.0 / (a * A + b * B + c * C)
    return np.stack([A * r, (c * h - b * i) * r, (b * f - c * e) * r,
                     B * r, (a * i - c * g) * r, (c * d - a * f) * r,
                     C * r, (b * g - a * h) * r, (a * e - b * d) * r], axis=1).reshape(-1, 3, 3)


_NO_TIMES = np.zeros(0, dtype=np.int64)
_NO_ROWS = np.zeros((0, 3))
_NO_VECTOR = np.zeros(3)


def _times(block: Block) -> np.ndarray:
    return np.ascontiguousarray(block.t_ns, dtype=np.int64)


class DecoupledSettings(AhrsSettings):
    PRESETS: ClassVar[dict[str, dict[str, Any]]] = {
        # hand-held motion (BROAD): VQF's published settings, every accelerometer reading in
        # full; the inertial-frame filter averages the hand's acceleration out, a gate would
        # weight it unevenly (docs/evaluation.md)
        "handheld": {"accel_soft_gate_g": None, "tau_acc_s": 3.0, "tau_acc_rest_s": None,
                     "turbulence_rate_deg_s": None, "innovation_speed_m_s": None,
                     "manoeuvre_speed_m_s": None, "gyro_relative_error": None},
        # the flight settings before the manoeuvre detector (issue 27): a fixed gate, 10 s
        # and the turbulence correction; kept to reproduce the earlier figures
        "flight": {"accel_soft_gate_g": 0.02, "tau_acc_s": 10.0, "tau_acc_rest_s": 3.0,
                   "turbulence_rate_deg_s": 3.0, "innovation_speed_m_s": None,
                   "manoeuvre_speed_m_s": None, "gyro_relative_error": None},
        # VQF's settings weighted by the innovation speed instead of a fixed gate: one
        # setting for both worlds, tried as the default and not good enough yet (BROAD's
        # fast translation and stationary-magnet trials; docs/estimators.md, decoupled)
        "adaptive": {"accel_soft_gate_g": None, "tau_acc_s": 3.0, "tau_acc_rest_s": None,
                     "turbulence_rate_deg_s": None, "innovation_speed_m_s": 1.0,
                     "manoeuvre_speed_m_s": None, "gyro_relative_error": None},
    }

    tau_acc_s: float = Field(3.0, gt=0.0)
    """Mean delay (s) of the accelerometer low-pass in the almost-inertial frame: the
    inclination correction's speed. Default VQF's published 3 s: what a vehicle's longer
    turns would add to it, the manoeuvre detector keeps out (``manoeuvre_speed_m_s``);
    ``preset: flight`` has 10 s and a gate instead (docs/estimators.md)."""
    tau_acc_rest_s: float | None = Field(None, gt=0.0)
    """At rest (``rest_detected``) the accelerometer filter runs with this time constant (s)
    instead: the specific force is gravity alone, what is left is gyro drift (``preset:
    flight`` 3 s: on the ground its 10 s filter converges as fast as the hand-held one).
    None (default): ``tau_acc_s`` always (VQF)."""
    accel_soft_gate_g: float | None = Field(None, gt=0.0)
    """Share of each step the inclination filter advances by, 1 / (1 + (| |a| - 1 g | /
    width)^2) (common/gate.py): a reading away from 1 g is trusted less (``preset: flight``
    0.02 g). None (default, VQF's choice): every reading in full, which hand-held motion
    needs (BROAD 9-DOF total 2.33 deg with ``preset: handheld``, 5.45 with ``preset:
    flight``): docs/estimators.md."""
    turbulence_rate_deg_s: float | None = Field(None, gt=0.0)
    """In straight flight through turbulence (gusts keep |a| off 1 g, so the soft gate stays
    closed; detected from the spread and mean of |a| and the turn rate, ``turbulence.py``)
    the filtered accelerometer is also turned towards each reading at up to this rate
    (deg/s) times the gate's closed share, as madgwick corrects: the gyro error of
    aerobatics is walked back instead of kept (flight benchmark `rc-flight` tilt RMS 1.2
    against 4.2 deg without; `thermal` unchanged; ``preset: flight`` 3). None (default):
    off; without a soft gate it never acts."""
    innovation_speed_m_s: float | None = Field(None, gt=0.0)
    """Weight each step of the accelerometer filter by the innovation speed
    (common/innovation.py): the filter's innovation (the reading minus its gravity,
    almost-inertial frame), its own mean over ``tau_acc_s`` taken out (a constant innovation
    is a tilt error), integrated across gravity into a speed with the leak
    ``innovation_tau_s`` and zeroed at rest; the step counts 1 / (1 + (speed / this)^2).
    ``preset: adaptive`` sets 1 m/s, a hand's speed. None (default): no such weight.
    Measured in docs/estimators.md (decoupled): it flies the flight targets, but BROAD's
    fast translation and stationary-magnet trials, where the hand moves faster, lose much."""
    innovation_tau_s: float = Field(1.0, gt=0.0)
    """Leak of that speed (s): hand motion and gusts turn round within about a second (0.5-2
    Hz); a velocity change kept longer is a manoeuvre's."""
    manoeuvre_speed_m_s: float | None = Field(8.0, gt=0.0)
    """The manoeuvre detector (common/innovation.py, ``ManoeuvreDetector``): the filter's
    innovation integrated into a velocity (3 s leak) beyond this speed (m/s) is a vehicle's
    manoeuvre, not a hand's, and the accelerometer filter stops following it (a sharp step:
    full weight at half this, none at twice it). 8 m/s: BROAD's fastest hand stays under
    5.4, `rc-flight`'s loop reaches 21. None: no manoeuvre detection (VQF,
    ``preset: handheld``)."""
    manoeuvre_ratio: float = Field(1.0, gt=0.0)
    """The detector's other statistic: the innovation's 0.5 s mean across gravity, against
    its scatter over the same window (at least 1 m/s^2), beyond this ratio is a steady
    acceleration (a take-off push, a launch, a banked turn). Hand motion stays under 0.6."""
    manoeuvre_lookback_s: float = Field(0.5, ge=0.0)
    """When the detector closes, the accelerometer filter is run again over this long (s)
    with the new weight: the stretch the detector needed to decide, which the filter had
    taken nearly in full (`rc-flight` tilt max 8.0 deg without, 4.0 with). What it withheld
    is filtered again in full when its velocity change comes back within the detector's
    leak time (a hand's stroke; decoupled/lookback.py)."""
    gyro_relative_error: float | None = Field(0.03, gt=0.0)
    """The gyro's relative error (scale factor and cross-axis sensitivity; 0.03: the
    MPU-9250's datasheet scale-factor tolerance, +-3 %): the strapdown turns away at this
    share of the rotation rate, so while the board rotates fast with little acceleration the
    accelerometer filter runs faster than ``tau_acc_s``, to the time constant sigma_a / (g
    this |omega|) (decoupled/pace.py). None: ``tau_acc_s`` always (VQF, ``preset:
    handheld``)."""
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
    motion_bias: bool = True
    """Estimate the gyro bias in motion too, from the inclination corrections (VQF's motion
    bias estimation); False: at rest only."""
    bias_sigma_init_deg_s: float = Field(0.5, gt=0.0)
    """Uncertainty of the gyro bias at the start (deg/s) (VQF: 0.5)."""
    bias_forgetting_s: float = Field(100.0, gt=0.0)
    """A bias known exactly is uncertain by 0.1 deg/s after this long (s) (VQF: 100)."""
    bias_sigma_motion_deg_s: float = Field(0.1, gt=0.0)
    """Uncertainty the motion updates settle the bias at (deg/s) (VQF: 0.1)."""
    bias_vertical_forgetting: float = Field(1e-4, gt=0.0)
    """Weight of the "no earth-vertical bias" pseudo-measurement relative to the motion
    updates (VQF: 1e-4): the vertical part is unobservable from the accelerometer."""
    bias_sigma_rest_deg_s: float = Field(0.03, gt=0.0)
    """Uncertainty the rest updates settle the bias at (deg/s) (VQF: 0.03)."""
    mag_norm_th: float = Field(0.1, gt=0.0)
    """A field whose norm differs from the reference by more than this fraction is disturbed."""
    mag_dip_th_deg: float = Field(10.0, gt=0.0)
    """A field whose dip differs from the reference by more than this (deg) is disturbed."""
    mag_new_s: float = Field(20.0, gt=0.0)
    """A disturbed field that stays consistent this long (s) becomes the new reference."""
    mag_min_clean_s: float = Field(5.0, ge=0.0)
    """Offline only: the field is fused only in undisturbed stretches at least this long (s);
    near a magnet single readings pass the check by chance."""
    mag_margin_s: float = Field(2.0, ge=0.0)
    """Offline only: nor within this long (s) of a disturbance (the field deviates below the
    thresholds while a magnet approaches and leaves)."""
    use_mag: bool = True
    """Fuse the magnetometer (9-DOF); False: 6-DOF even when magnetometer samples arrive."""
    offline: bool = False
    """Forward-backward smoothing over a whole recording (estimate/evaluate only)."""

    def params(self) -> DecoupledParams:
        g = 9.80665
        return DecoupledParams(
            tau_acc_s=self.tau_acc_s, tau_acc_rest_s=self.tau_acc_rest_s,
            tau_mag_s=self.tau_mag_s,
            accel_soft_gate_g=self.accel_soft_gate_g,
            innovation_speed_m_s=self.innovation_speed_m_s,
            innovation_tau_s=self.innovation_tau_s,
            manoeuvre=None if self.manoeuvre_speed_m_s is None else ManoeuvreParams(
                speed_m_s=self.manoeuvre_speed_m_s, ratio=self.manoeuvre_ratio),
            lookback_s=self.manoeuvre_lookback_s,
            gyro_relative_error=self.gyro_relative_error,
            rest_gyro_th_rad_s=math.radians(self.rest_gyro_th_deg_s),
            rest_acc_th_g=self.rest_acc_th_m_s2 / g, rest_min_s=self.rest_min_s,
            bias_clip_rad_s=math.radians(self.bias_clip_deg_s),
            bias=BiasParams(
                sigma_init_deg_s=self.bias_sigma_init_deg_s,
                forgetting_s=self.bias_forgetting_s,
                sigma_motion_deg_s=self.bias_sigma_motion_deg_s if self.motion_bias else None,
                vertical_forgetting=self.bias_vertical_forgetting,
                sigma_rest_deg_s=self.bias_sigma_rest_deg_s,
                clip_rad_s=math.radians(self.bias_clip_deg_s)),
            mag_norm_th=self.mag_norm_th, mag_dip_th_deg=self.mag_dip_th_deg,
            mag_new_s=self.mag_new_s,
            turbulence_rate_rad_s=None if self.turbulence_rate_deg_s is None
            else math.radians(self.turbulence_rate_deg_s))


class DecoupledEstimator(AhrsEstimator):
    """VQF's method in imuhal: inclination from gyro strapdown plus the accelerometer
    low-passed in an almost-inertial frame, rest-detected gyro bias, separate heading with
    magnetic disturbance rejection (6-DOF, or 9-DOF when magnetometer samples arrive)."""

    owns_quaternion = False  # its kernel keeps the attitude (angular-rate recovery)

    name: ClassVar[str] = "decoupled"
    description: ClassVar[str] = (
        "VQF-style AHRS: inertial-frame accel filtering, rest gyro bias, separate heading "
        "with magnetic disturbance rejection; offline forward-backward mode"
    )
    Settings: ClassVar[type[DecoupledSettings]] = DecoupledSettings
    settings: DecoupledSettings

    def _reset_filter(self) -> None:
        self._kernel = DecoupledKernel(self.settings.params())
        self._kernel.start(self._q)
        # the compiled step where it pays (the AOT extension; fast.py) and covers the
        # settings (packed.covers); its state lives in arrays packed from the kernel, which
        # is brought up to date (_synced) before anything reads it
        self._sample_kernel = None
        if not self.settings.offline and covers(self._kernel.p):
            self._sample_kernel = decoupled_sample.per_sample()
        if self._sample_kernel is not None:
            self._params = params_array(self._kernel.p)
            self._pack()

    def _pack(self) -> None:
        self._state, self._look = pack(self._kernel)

    def _synced(self) -> DecoupledKernel:
        """The kernel, with the compiled step's state written back into it."""
        if self._sample_kernel is not None:
            unpack(self._state, self._look, self._kernel)
        return self._kernel

    def _on_aligned(self) -> None:
        k = self._synced()
        k.start(self._q, k.bias)
        if self._sample_kernel is not None:
            self._pack()

    def _reseat_tilt(self, q: Quat) -> None:
        self._synced().reseat(q)
        if self._sample_kernel is not None:
            self._pack()

    # ------------------------------------------------------------------ block step
    _block_call: Any = None

    def _has_block_step(self) -> bool:
        # the block step runs beside the per-sample one, on the same state arrays
        if self._sample_kernel is None:
            return False
        if self._block_call is None:
            self._block_call = decoupled_block.unchecked() if decoupled_block.available() \
                else False
        return self._block_call is not False

    def _block_kernel(self) -> bool:
        return self._has_block_step()

    def _kernel_allowed(self) -> bool:
        """The block step covers turn compensation by the nominal airspeed, not by a
        velocity or airspeed source (then frame by frame)."""
        return self._has_block_step() and not (
            self.settings.turn_compensation and self._kinematics.has_speed_source)

    def _row_kernel_blocks(self, gyro: Block, accel: Block | None, mag: Block | None
                           ) -> list[Estimate | AttitudeBlock]:
        """Blocks the block step does not take: the frames one by one (there is no row
        kernel)."""
        return list(Estimator.update_blocks(
            self, [b for b in (accel, mag, gyro) if b is not None]))

    def _block_step(self, gyro: Block, accel: Block | None, mag: Block | None
                    ) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray] | None:
        """``AhrsEstimator._block_step`` in ``decoupled_block`` (the same floats as the
        frames one by one: tests/filters/test_decoupled_compiled.py)."""
        if accel is None or not self._has_block_step():
            return None
        s = self.settings
        m = len(gyro)
        out, diag, dts, lin = np.empty((m, 4)), np.empty((m, 6)), np.empty(m), np.empty((m, 3))
        speed = s.nominal_airspeed_m_s if s.turn_compensation else None
        last = self._last_gyro_t_ns
        mag_t, mag_v = (_NO_TIMES, _NO_ROWS) if mag is None else \
            (_times(mag), c_array(mag.values))
        held, held_t = self._mag_ut, self._mag_t_ns
        max_age = s.max_aux_age_s
        turn_sum, fallbacks, stale, ok = self._block_call(
            self._state, self._params, self._look, _times(gyro), c_array(gyro.values),
            _times(accel), c_array(accel.values), mag_t, mag_v, mag is not None,
            self.uses_mag, s.use_mag, _NO_VECTOR if held is None else np.array(held),
            0 if held_t is None else held_t, held is not None and held_t is not None,
            math.nan if max_age is None else float(max_age), 0 if last is None else last,
            last is not None, self._gyro_fs, self._accel_fs, float(s.sample_period_s),
            s.dt_from_timestamps, float(s.max_dt_s), math.nan if speed is None else
            float(speed), s.turn_compensation, self._kinematics.turn_sum, out, diag, dts, lin)
        if not ok:
            return None
        self._block_step_done(gyro, accel, mag, fallbacks)
        self._counters["stale_mag"] += stale
        self._kernel_finished(out[-1], m, 0, turn_sum)
        return out, diag, dts, lin

    def _kernel_row_diagnostics(self, dts: FloatArray, diag: FloatArray, source: str
                                ) -> list[dict[str, Any]]:
        return [{"dt_s": dt, "turn_compensation": source, "rest_detected": r == 1.0,
                 "mag_disturbed": None if d != d else d == 1.0,
                 "gyro_bias_rad_s": [bx, by, bz], "accel_used": True, "mag_used": u == 1.0}
                for dt, (r, d, bx, by, bz, u) in zip(dts.tolist(), diag.tolist(),
                                                     strict=True)]

    def _compiled_step(self, gyro: Vec, accel_m_s2: Vec | None, mag: Vec | None, dt: float,
                       measured_m_s2: Vec | None) -> dict[str, Any]:
        """``_step`` in the compiled per-sample kernel: the same floats (tests compare them)."""
        s = self._state
        if s[-1] + 2.0 > self._look.shape[0]:
            # a step keeps at most one more look-back entry; the ring fills only while an
            # episode keeps its input: grow it
            self._look = grown(s, self._look)
        a = accel_m_s2 is not None
        ax, ay, az = gravity_positive_g(accel_m_s2) if a else (0.0, 0.0, 0.0)  # type: ignore[arg-type]  # a: accel_m_s2 given
        use_m = mag is not None and self.settings.use_mag
        mx, my, mz = mag if use_m else (0.0, 0.0, 0.0)  # type: ignore[misc]  # use_m: mag given
        fx, fy, fz = (0.0, 0.0, 0.0) if measured_m_s2 is None else measured_m_s2
        gx, gy, gz = gyro
        w, x, y, z, lx, ly, lz, rest, disturbed = self._sample_kernel(
            s, self._params, self._look, gx, gy, gz, a, ax, ay, az, use_m, mx, my, mz, dt,
            fx, fy, fz)
        self._q = (w, x, y, z)
        self._linear_ned = (lx, ly, lz)
        return {"dt_s": dt, "turn_compensation": self._kinematics.source,
                "rest_detected": rest, "mag_disturbed": disturbed if use_m else None,
                "gyro_bias_rad_s": s[44:47].tolist(), "accel_used": a,
                "mag_used": use_m and not disturbed}

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
        k = self._synced()
        return {"q_gyro": list(k.q_gyro), "q_inc": list(k.q_inc), "delta_rad": k.delta_rad,
                "acc_i": None if k.acc_i is None else list(k.acc_i),
                "acc_filter": k._acc_filter.state, "r_filter": k._r_filter.state,
                "rb_filter": k._rb_filter.state, "bias": list(k.bias),
                "bias_p": [list(row) for row in k.kf.p],
                "gyro_lp": None if k.gyro_lp is None else list(k.gyro_lp),
                "acc_lp": None if k.acc_lp is None else list(k.acc_lp), "rest_s": k.rest_s,
                "mag_ref": None if k.mag_ref is None else list(k.mag_ref),
                "mag_cand": None if k.mag_cand is None else list(k.mag_cand),
                "mag_cand_s": k.mag_cand_s, "mag_disturbed": k.mag_disturbed,
                "accel_missed": k.accel_missed,
                "innovation": None if k.innovation is None else k.innovation.as_list(),
                "straight_flight": k.straight.as_list(),
                "manoeuvre": None if k.manoeuvre is None else k.manoeuvre.as_list(),
                "lookback": None if k.lookback is None else k.lookback.as_dict(),
                "pace": None if k.pace is None else k.pace.as_list()}

    def _set_filter_state(self, state: dict[str, Any]) -> None:
        k = self._kernel

        def tup(v: Any) -> Any:
            return None if v is None else tuple(float(c) for c in v)

        k.q_gyro, k.q_inc = tup(state["q_gyro"]), tup(state["q_inc"])
        k.delta_rad, k.acc_i = float(state["delta_rad"]), tup(state["acc_i"])
        k.kf.b = tup(state["bias"])
        k.kf.p = [[float(c) for c in row] for row in state["bias_p"]]
        for name, filt in (("acc_filter", k._acc_filter), ("r_filter", k._r_filter),
                           ("rb_filter", k._rb_filter)):
            filt.state = None if state[name] is None else [float(c) for c in state[name]]
        k.gyro_lp, k.acc_lp, k.rest_s = tup(state["gyro_lp"]), tup(state["acc_lp"]), \
            float(state["rest_s"])
        k.mag_ref, k.mag_cand = tup(state["mag_ref"]), tup(state["mag_cand"])
        k.mag_cand_s, k.mag_disturbed = float(state["mag_cand_s"]), bool(state["mag_disturbed"])
        k.accel_missed = bool(state.get("accel_missed", False))  # absent before the restart
        if k.innovation is not None and state.get("innovation") is not None:
            k.innovation.load_list(state["innovation"])  # absent before the adaptive weight
        if "straight_flight" in state:  # absent from states saved before the detector
            k.straight.load_list(state["straight_flight"])
        if k.manoeuvre is not None and state.get("manoeuvre") is not None:
            self._load_manoeuvre(state)
        if k.pace is not None and state.get("pace") is not None:  # absent before the pace
            k.pace.load_list(state["pace"])
        if self._sample_kernel is not None:
            self._pack()

    def _load_manoeuvre(self, state: dict[str, Any]) -> None:
        """The manoeuvre detector and the look-back (absent before them; a look-back saved
        before its episodes starts empty)."""
        k = self._kernel
        assert k.manoeuvre is not None and k.lookback is not None
        k.manoeuvre.load_list(state["manoeuvre"])
        if isinstance(state.get("lookback"), dict):
            k.lookback.load_dict(state["lookback"])

    # ------------------------------------------------------------------ offline
    def _pass(self, gyro: FloatArray, acc_g: FloatArray, mag: FloatArray | None,
              sign: float) -> PassRecord:
        """One causal pass of the kernel over the rows (``sign`` -1: rows already reversed,
        gyro negated: time reversal) from the attitude aligned on the first row; what it
        learnt, in its row order, the bias in forward time's sign."""
        k = DecoupledKernel(self.settings.params())
        q0 = aligned_quaternion(tuple(acc_g[0]),
                                None if mag is None else tuple(mag[0]))
        k.start(IDENTITY if q0 is None else q0)
        n = gyro.shape[0]
        bias, info = np.zeros((n, 3)), np.zeros((n, 3, 3))
        disturbed = np.zeros(n, dtype=bool)
        dt = self.settings.sample_period_s
        # the row kernel where the AOT extension has it (or IMUHAL_KERNELS=jit forces the
        # JIT), as the per-sample step: compiling the whole step on numba's JIT costs about
        # 20 s of CPU at the first use in a process with a cold cache (docs/performance.md)
        rows = decoupled_rows.per_sample() if covers(k.p) else None
        if rows is not None:
            info = _information(self._compiled_pass(rows, k, sign * gyro, acc_g, mag, bias,
                                                    disturbed))
            return PassRecord(sign * bias, info, disturbed)
        gyros, accs = (sign * gyro).tolist(), acc_g.tolist()
        mags = None if mag is None else mag.tolist()
        for i in range(n):
            k.step(gyros[i], accs[i], None if mags is None else mags[i], dt)
            bias[i] = k.bias
            info[i] = k.kf.information()
            disturbed[i] = k.mag_disturbed
        return PassRecord(sign * bias, info, disturbed)

    def _compiled_pass(self, rows: Any, k: DecoupledKernel, gyro: FloatArray,
                       acc_g: FloatArray, mag: FloatArray | None, bias: FloatArray,
                       disturbed: np.ndarray) -> FloatArray:
        """``_pass``'s rows through the compiled row kernel ``rows`` from ``k``'s state:
        fills ``bias`` and ``disturbed``; returns the bias covariance after each row
        (n, 9)."""
        n = gyro.shape[0]
        state, look = pack(k)
        cov = np.zeros((n, 9))
        g, a = c_array(gyro), c_array(acc_g)
        m = np.zeros((n, 3)) if mag is None else c_array(mag)
        done = 0
        while done < n:
            done += int(rows(state, params_array(k.p), look, g[done:], a[done:], m[done:],
                             mag is not None, self.settings.sample_period_s, bias[done:],
                             cov[done:], disturbed[done:]))
            if done < n:
                look = grown(state, look)
        return cov

    def smooth(self, gyro_rad_s: FloatArray, accel_m_s2: FloatArray,
               mag_ut: FloatArray | None) -> FloatArray:
        """Forward-backward smoothing over a whole recording (``smoother.py``): (N, 3) body
        NED arrays (rad/s, specific force m/s^2, uT), one row per gyro sample at
        ``sample_period_s``, no gaps; returns the (N, 4) body -> NED quaternions. Turn
        compensation needs live speed samples and is not applied here."""
        mag = mag_ut if self.settings.use_mag else None
        n = gyro_rad_s.shape[0]
        if n == 0:
            return np.zeros((0, 4))
        rev = slice(None, None, -1)
        acc_g = -accel_m_s2 / STANDARD_GRAVITY_M_S2
        fwd = self._pass(gyro_rad_s, acc_g, mag, 1.0)
        bwd = self._pass(gyro_rad_s[rev], acc_g[rev], None if mag is None else mag[rev], -1.0)
        bwd = PassRecord(bwd.bias_rad_s[rev], bwd.information[rev], bwd.mag_disturbed[rev])
        bias = fused_bias(fwd, bwd)
        first = aligned_quaternion(tuple(acc_g[0]),
                                   None if mag is None else tuple(mag[0]))
        dt = self.settings.sample_period_s
        q_gyro = strapdown(IDENTITY if first is None else first, gyro_rad_s, bias, dt)
        acc_i = zero_phase(rotate_rows(q_gyro, acc_g), self.settings.tau_acc_s, dt)
        q6 = inclination(q_gyro, acc_i)
        if mag is None:
            return q6
        st = self.settings
        trusted = clean_field(fwd.mag_disturbed & bwd.mag_disturbed, st.mag_min_clean_s,
                              st.mag_margin_s, dt)
        w = field_weights(rotate_rows(q6, mag), trusted, st.mag_norm_th,
                          math.radians(st.mag_dip_th_deg))
        return apply_heading(q6, heading(q6, mag, w, st.tau_mag_s, dt))
