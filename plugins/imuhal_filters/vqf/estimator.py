"""The "vqf" estimator: VQF (Laidig and Seel, "VQF: Highly Accurate IMU Orientation
Estimation with Bias Estimation and Magnetic Disturbance Rejection", Information Fusion 91,
2023) through the maintained ``vqf`` package, as an imuhal AHRS plugin.

Each gyro step hands the package the latest accelerometer and magnetometer sample, converted
at the edge to its conventions (frames.py), and reports its rest detection, magnetic
disturbance detection and gyro bias estimate on every estimate. VQF runs at a fixed sample
period (``sample_period_s``: set it to the gyro rate), starts from its own initial state (its
accelerometer low-pass starts at the first sample, so it needs no alignment step) and its
9-DOF heading converges from the magnetometer within seconds.

``use_mag: false`` gives the 6-DOF estimate (gyro + accelerometer, heading drifts with the
gyro) even when magnetometer samples arrive. ``offline: true`` is the package's acausal
variant (the whole recording known in advance: forward-backward bias and disturbance
estimation); it has no live form, so only ``imuhal estimate`` and ``imuhal evaluate`` run it
(``smooth``).
"""

from __future__ import annotations

import math
from typing import Any, ClassVar, Literal

import numpy as np
from pydantic import Field
from vqf import VQF, offlineVQF

from imuhal.core.atmosphere import STANDARD_GRAVITY_M_S2
from imuhal.core.conventions import VectorKind
from imuhal.core.frames import FloatArray
from imuhal_filters.common.ahrs import AhrsEstimator, AhrsSettings, ImuStep
from imuhal_filters.common.innovation import InnovationSpeed, ManoeuvreDetector, ManoeuvreParams
from imuhal_filters.common.quat import Quat, multiply, to_global
from imuhal_filters.vqf.frames import from_vqf, quat_from_vqf, quat_to_vqf, to_vqf, vector_to_vqf


class VqfSettings(AhrsSettings):
    initial_attitude: Literal["identity", "first_sample"] = "identity"
    """VQF initialises itself from the first accelerometer (and magnetometer) samples; the
    default ``identity`` leaves that to it so outputs equal the package's own.
    ``first_sample`` is refused for this estimator (its internal state would disagree)."""
    sample_period_s: float = Field(0.005, gt=0.0)
    """The gyro period VQF runs at (s); it takes no per-step time."""
    use_mag: bool = True
    """Fuse the magnetometer (9-DOF); False: the 6-DOF quaternion."""
    offline: bool = False
    """The package's offline (forward-backward) variant; estimate/evaluate only."""
    tau_acc_s: float = Field(3.0, gt=0.0)
    """Accelerometer low-pass/correction time constant (s), VQF's ``tauAcc`` (default 3)."""
    tau_mag_s: float = Field(9.0, gt=0.0)
    """Magnetometer correction time constant (s), VQF's ``tauMag`` (default 9)."""
    motion_bias_estimation: bool = True
    """Gyro bias estimation during motion (VQF's ``motionBiasEstEnabled``)."""
    rest_bias_estimation: bool = True
    """Gyro bias estimation during rest (``restBiasEstEnabled``)."""
    mag_disturbance_rejection: bool = True
    """Magnetic disturbance detection and rejection (``magDistRejectionEnabled``)."""
    withhold_speed_m_s: float | None = Field(None, gt=0.0)
    """Input preprocessing for flight without a speed source, VQF itself untouched: a reading
    is not handed to VQF while its innovation against VQF's own inclination, integrated into
    a speed across gravity (common/innovation.py: 1 s leak, the innovation's ``tau_acc_s``
    mean taken out, zeroed at rest), exceeds this (m/s). 3 m/s: `rc-flight` tilt max 6.9 deg
    instead of 40.5; but BROAD's fast translation trial 15 then loses 2.31 -> 5.26 deg, and
    at 6 m/s, where BROAD is unchanged, `rc-flight` keeps 22 deg (docs/estimators.md, vqf).
    None (default): every reading, the package's own filter."""
    withhold_tau_s: float = Field(1.0, gt=0.0)
    """The leak of that speed (s): how long hand motion and gusts take to come back."""
    manoeuvre_speed_m_s: float | None = Field(8.0, gt=0.0)
    """Input preprocessing, VQF itself untouched: a reading is not handed to VQF while the
    manoeuvre detector (common/innovation.py, ``ManoeuvreDetector``, decoupled's default),
    fed the reading's innovation against VQF's own inclination, sees what no hand does: a
    leaky velocity beyond this (m/s) or a steady acceleration beyond ``manoeuvre_ratio``
    times its scatter (docs/estimators.md, vqf). None: every reading, the package's filter
    as published."""
    manoeuvre_ratio: float = Field(1.0, gt=0.0)
    """The detector's steadiness bound (mean across gravity over its scatter)."""

    def vqf_params(self) -> dict[str, Any]:
        return {"tauAcc": self.tau_acc_s, "tauMag": self.tau_mag_s,
                "motionBiasEstEnabled": self.motion_bias_estimation,
                "restBiasEstEnabled": self.rest_bias_estimation,
                "magDistRejectionEnabled": self.mag_disturbance_rejection}


class VqfEstimator(AhrsEstimator):
    """VQF via the ``vqf`` package (6-DOF, or 9-DOF when magnetometer samples arrive)."""

    owns_quaternion = False  # its kernel keeps the attitude (angular-rate recovery)

    name: ClassVar[str] = "vqf"
    description: ClassVar[str] = (
        "VQF (Laidig and Seel 2023): rest and motion gyro bias estimation, magnetic "
        "disturbance rejection (optional `vqf` package)"
    )
    Settings: ClassVar[type[VqfSettings]] = VqfSettings
    settings: VqfSettings

    def _reset_filter(self) -> None:
        if self.settings.initial_attitude != "identity":
            raise ValueError(f"{self.instance}: vqf aligns itself; initial_attitude must be "
                             "'identity'")
        self._vqf = VQF(self.settings.sample_period_s, **self.settings.vqf_params())
        self._mag_seen = False
        speed = self.settings.withhold_speed_m_s
        self._innovation = None if speed is None else InnovationSpeed(
            self.settings.withhold_tau_s, speed, self.settings.tau_acc_s)
        self._withheld = 0
        m = self.settings.manoeuvre_speed_m_s
        self._manoeuvre = None if m is None else ManoeuvreDetector(
            ManoeuvreParams(speed_m_s=m, ratio=self.settings.manoeuvre_ratio))

    def _passes(self, accel_g: tuple[float, float, float], dt: float) -> bool:
        """Whether this reading (gravity positive, g, body NED) goes to VQF: its innovation
        against VQF's inclination, integrated across gravity, within the speed bound."""
        inn, det = self._innovation, self._manoeuvre
        if inn is None and det is None:
            return True
        v = self._vqf
        rest = v.getRestDetected()
        up = to_global(quat_from_vqf(v.getQuat6D()), accel_g)
        weight = 1.0
        for stat in (inn, det):
            if stat is not None:
                if rest:
                    stat.reset()
                # weight 1 / (1 + (speed / bound)^2) below one half: beyond the bound
                weight *= stat.weight(up, (0.0, 0.0, 1.0), dt)
        if weight >= 0.5:
            return True
        self._withheld += 1
        return False

    def _step(self, step: ImuStep) -> dict[str, Any]:
        if self.settings.offline:
            raise ValueError(f"{self.instance}: offline: true needs the whole recording; run it "
                             "with `imuhal estimate` or `imuhal evaluate`, not live")
        v = self._vqf
        v.updateGyr(vector_to_vqf(step.gyro_rad_s, VectorKind.ANGULAR_RATE))
        passed = step.accel_g is not None and self._passes(step.accel_g, step.dt_s)
        if passed:
            assert step.accel_g is not None
            g = -STANDARD_GRAVITY_M_S2
            f_ned = (step.accel_g[0] * g, step.accel_g[1] * g, step.accel_g[2] * g)
            v.updateAcc(vector_to_vqf(f_ned, VectorKind.SPECIFIC_FORCE))
        mag = step.mag_ut if self.settings.use_mag else None
        if mag is not None:
            v.updateMag(vector_to_vqf(mag, VectorKind.MAGNETIC_FIELD))
            self._mag_seen = True
        q = v.getQuat9D() if self._mag_seen else v.getQuat6D()
        self._q = quat_from_vqf(q)
        bias_flu = v.getBiasEstimate()[0]
        # FRD <-> FLU is its own inverse
        bias_ned = vector_to_vqf(tuple(bias_flu), VectorKind.ANGULAR_RATE)
        return {
            "rest_detected": bool(v.getRestDetected()),
            # None without a magnetometer: VQF then reports its initial "disturbed" state
            "mag_disturbed": bool(v.getMagDistDetected()) if self._mag_seen else None,
            "gyro_bias_rad_s": [float(c) for c in bias_ned],
            "accel_used": passed,
            "mag_used": mag is not None,
            "accel_withheld": self._withheld,
        }

    def _reseat_tilt(self, q: Quat) -> None:
        """Through the package's own state: its strapdown (``gyrQuat``) set to ``q`` less
        its heading correction (``delta``, kept: the 9-DOF output stays q), its inclination
        correction (``accQuat``) to none, its accelerometer low-pass steady at gravity
        (``filterInitialState``; left in ``resetState``'s averaging phase, its first
        readings moved it whole: a yaw turn's mis-compensated reading put it 77 deg off
        within 0.2 s of a re-seat on the seed board), the motion bias low-passes of the
        rotation as ``resetState`` leaves them (what they held was the corrupted
        attitude); its bias, rest detection and magnetic reference kept."""
        v = self._vqf
        fresh = VQF(self.settings.sample_period_s, **self.settings.vqf_params()).state
        state = dict(v.state)
        half = -0.5 * float(state["delta"])
        # quatApplyDelta's inverse: VQF's 9-DOF quaternion is its 6-DOF one turned by delta
        # about the ENU vertical
        state["gyrQuat"] = multiply((math.cos(half), 0.0, 0.0, math.sin(half)),
                                    tuple(float(c) for c in quat_to_vqf(q)))  # type: ignore[arg-type]  # four floats
        for key in ("accQuat", "lastAccCorrAngularRate", "motionBiasEstRLpState",
                    "motionBiasEstBiasLpState"):
            state[key] = fresh[key]
        # gravity in its almost-inertial frame, which the new strapdown makes ENU's up
        coeffs = v.coeffs
        up = (0.0, 0.0, STANDARD_GRAVITY_M_S2)
        state["lastAccLp"] = list(up)
        b, a = np.asarray(coeffs["accLpB"], dtype=float), np.asarray(coeffs["accLpA"],
                                                                     dtype=float)
        state["accLpState"] = [float(c) for x0 in up
                               for c in VQF.filterInitialState(x0, b, a)]
        v.state = state
        self._q = q

    def diagnostics(self) -> dict[str, Any]:
        return {**super().diagnostics(), "accel_withheld": self._withheld}

    def _filter_state(self) -> dict[str, Any]:
        # the package's state is plain lists, floats and bools
        return {"vqf": dict(self._vqf.state), "mag_seen": self._mag_seen,
                "innovation": None if self._innovation is None
                else self._innovation.as_list(), "withheld": self._withheld,
                "manoeuvre": None if self._manoeuvre is None else self._manoeuvre.as_list()}

    def _set_filter_state(self, state: dict[str, Any]) -> None:
        self._vqf.state = dict(state["vqf"])
        self._mag_seen = bool(state["mag_seen"])
        if self._innovation is not None and state.get("innovation") is not None:
            self._innovation.load_list(state["innovation"])
        if self._manoeuvre is not None and state.get("manoeuvre") is not None:
            self._manoeuvre.load_list(state["manoeuvre"])  # absent before the detector
        self._withheld = int(state.get("withheld", 0))

    def smooth(self, gyro_rad_s: FloatArray, accel_m_s2: FloatArray,
               mag_ut: FloatArray | None) -> FloatArray:
        """The offline variant over a whole recording: (N, 3) body NED arrays (specific
        force), one row per gyro sample at ``sample_period_s``; returns (N, 4) body -> NED."""
        use_mag = mag_ut is not None and self.settings.use_mag
        out = offlineVQF(to_vqf(gyro_rad_s, VectorKind.ANGULAR_RATE),
                         to_vqf(accel_m_s2, VectorKind.SPECIFIC_FORCE),
                         to_vqf(mag_ut, VectorKind.MAGNETIC_FIELD) if use_mag else None,  # type: ignore[arg-type]  # use_mag is False when mag_ut is None: the argument is not evaluated then
                         self.settings.sample_period_s, self.settings.vqf_params())
        return from_vqf(out["quat9D"] if use_mag else out["quat6D"])
