"""The indirect complementary Kalman filter of Freescale sensor fusion (build 422, fusion.c).

One ``step`` is one pass of fRun_6DOF_GY_KALMAN / fRun_9DOF_GBY_KALMAN, in the reference's
units and coordinate system (see ``coords``): accelerometer in g, magnetometer in uT
(calibrated), gyro in deg/s, angles and the orientation error in degrees.

The filter estimates an *error* vector, re-zeroed after every step:

* theta (3, deg): by how much the a priori orientation exceeds the truth,
* b (3, deg/s): gyro offset error,
* a (3, g, sensor frame): linear acceleration error,
* d (3, uT, sensor frame, 9DOF only): magnetic disturbance error.

Each step (1) integrates the buffered fast gyro samples minus the offset estimate onto the
last orientation (a priori), (2) predicts gravity and the geomagnetic vector in the sensor
frame from it, (3) compares them with the accelerometer (plus the decayed linear
acceleration estimate) and the magnetometer, (4) maps that 3- or 6-element measurement error
through the gain K = Qw C^T (C Qw C^T + Qv)^-1 onto the error vector, (5) corrects the
orientation, offset and acceleration, (6) tracks the geomagnetic inclination from d, and
(7) rebuilds the process covariance Qw from the a posteriori covariance. In a window the
rest detector found the board still through (``at_rest``; not in build 422) the gates are
off and, between (4) and (5), the window's mean gyro reading is fused as a measurement of
the offset (a second, sequential update). A magnetic error
power |d|^2 above (2B)^2 flags magnetic jamming: then only the gravity columns of K correct
orientation, offset and acceleration, and the inclination is left alone.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from imuhal.core.frames import FloatArray
from imuhal_filters.common.fast_ahrs import soft_gate_distrust
from imuhal_filters.freescale.coords import (
    DEG,
    CoordinateSystem,
    ecompass,
    euler_angles_deg,
    matrix_from_quat,
    normalise_positive,
    quat_from_matrix_fsl,
    quat_from_rotvec_deg,
    quat_mul,
    skew,
    tilt_matrix,
)
from imuhal_filters.freescale.settings import Freescale9DofSettings, FreescaleCommonSettings

TH, B, A, D = slice(0, 3), slice(3, 6), slice(6, 9), slice(9, 12)
"""Blocks of the error vector: orientation, gyro offset, linear acceleration, disturbance."""
GATE_CLOSED, GATE_COS, GATE_SIN, GATE_LENGTH = 0, 1, 2, 3
"""Entries of ``FreescaleKalman.mag_gate``."""
FIELD_LENGTH_RATE_UT_S = 0.2
"""How fast (uT/s) the magnetometer gate's field length moves towards each step's measured
length, by this much whatever the difference: it follows the median of the measured length,
which a magnet held to the board for seconds (hundreds of uT) moves by tenths of a uT. The
Earth's field at a site does not change; the lock measures it, and this corrects a lock
taken in a disturbance (10 uT in 50 s)."""


@dataclass(frozen=True)
class KalmanStep:
    """What one Kalman step produced (reference units and coordinate system)."""

    valid: bool
    """False for the initialising step, which estimates nothing."""
    q_sensor_to_global: FloatArray
    """A posteriori orientation quaternion (scalar >= 0), sensor -> global of the system."""
    euler_deg: dict[str, float]
    """The system's own Euler angles: phi, theta, psi (0..360), rho (heading), chi (tilt)."""
    gyro_offset_dps: FloatArray
    """Gyro offset estimate b+ (deg/s, sensor axes)."""
    omega_dps: FloatArray
    """Angular velocity: window-average gyro minus the previous offset estimate (deg/s)."""
    linear_accel_sensor_g: FloatArray
    """A posteriori linear acceleration estimate a+ (g, sensor axes, the system's sign)."""
    linear_accel_global_g: FloatArray
    """Accelerometer reading rotated to the global frame with gravity removed (g); NED and
    Windows 8 give it as acceleration positive (sign flipped), as the reference does."""
    inclination_deg: float
    """Geomagnetic inclination being tracked (9DOF; 0 for 6DOF)."""
    mag_jamming: bool
    """Magnetic jamming detected this step (9DOF; always False for 6DOF)."""


class FreescaleKalman:
    """fRun_9DOF_GBY_KALMAN (``use_mag=True``, 12 states) or fRun_6DOF_GY_KALMAN (9 states)."""

    def __init__(self, settings: FreescaleCommonSettings, *, use_mag: bool) -> None:
        if use_mag and not isinstance(settings, Freescale9DofSettings):
            raise TypeError("the 9DOF filter needs Freescale9DofSettings")
        self.s = settings
        self.use_mag = use_mag
        self.n = 12 if use_mag else 9
        self.reset()

    # -- state --------------------------------------------------------------------------------

    def reset(self) -> None:
        """Back to power-on: the next step only initialises (if the settings say so)."""
        self.initialised = not self.s.initialise_on_first_step
        self._init_state()

    def _init_state(self) -> None:
        s = self.s
        self.locked = False
        self.gate_closed_s = 0.0
        self.mag_gate = np.zeros(4)
        """The magnetometer gate's state (``_mag_gate_verdict``): how long (s) it has
        rejected innovations one heading offset explains, the sums of that stretch's
        offsets' cosines and sines (their circular mean), and the field length it expects
        (uT; 0 until the lock measures it)."""
        self.q = np.array([1.0, 0.0, 0.0, 0.0])
        self.b = np.zeros(3)
        self.a_sensor = np.zeros(3)
        self.inclination_deg = 0.0
        self.m_global = np.zeros(3)
        if self.use_mag:
            field = self._field()
            # the reference starts at zero inclination, pointing north
            north = 0 if s.coordinate_system is CoordinateSystem.NED else 1
            self.m_global[north] = field
        qw = np.zeros((self.n, self.n))
        for i in range(3):
            qw[i, i] = s.qw_init_theta_deg2
            qw[3 + i, 3 + i] = s.qw_init_offset_dps2
            qw[i, 3 + i] = qw[3 + i, i] = s.qw_init_theta_offset
            qw[6 + i, 6 + i] = s.qw_init_accel_g2
            if self.use_mag:
                qw[9 + i, 9 + i] = self._s9().qw_init_disturbance_ut2
        self.qw = qw

    def _s9(self) -> Freescale9DofSettings:
        assert isinstance(self.s, Freescale9DofSettings)
        return self.s

    def _field(self) -> float:
        return self._s9().field_strength_ut

    def as_dict(self) -> dict[str, Any]:
        """JSON-serialisable snapshot."""
        return {
            "initialised": self.initialised, "locked": self.locked,
            "q": self.q.tolist(), "b": self.b.tolist(), "a_sensor": self.a_sensor.tolist(),
            "inclination_deg": self.inclination_deg, "m_global": self.m_global.tolist(),
            "qw": self.qw.tolist(), "gate_closed_s": self.gate_closed_s,
            "mag_gate": self.mag_gate.tolist(),
        }

    def load_dict(self, d: dict[str, Any]) -> None:
        self.initialised = bool(d["initialised"])
        self.locked = bool(d["locked"])
        self.q = np.array(d["q"], dtype=float)
        self.b = np.array(d["b"], dtype=float)
        self.a_sensor = np.array(d["a_sensor"], dtype=float)
        self.inclination_deg = float(d["inclination_deg"])
        self.gate_closed_s = float(d.get("gate_closed_s", 0.0))
        self.mag_gate = np.array(d.get("mag_gate", [0.0] * 4), dtype=float)
        self.m_global = np.array(d["m_global"], dtype=float)
        qw = np.array(d["qw"], dtype=float)
        if qw.shape != (self.n, self.n):
            raise ValueError(f"covariance shape {qw.shape} does not fit a {self.n}-state filter")
        self.qw = qw

    # -- one Kalman step ----------------------------------------------------------------------

    def step(self, accel_g: FloatArray, gyro_fast_dps: FloatArray,
             mag_ut: FloatArray | None = None, *, at_rest: bool = False) -> KalmanStep:
        """One Kalman pass.

        ``gyro_fast_dps`` holds the oversample_ratio buffered gyro samples (rows, deg/s) of
        the window just ended; ``accel_g`` and ``mag_ut`` are the measurements the step fuses.
        ``at_rest``: the rest detector found the board still through the whole window
        (``rest.WindowRest``): the accelerometer is fused without the gates, and the
        window's mean gyro reading is fused as a measurement of the offset
        (:meth:`_fuse_rest_offset`).
        """
        s = self.s
        cs = s.coordinate_system
        accel = np.asarray(accel_g, dtype=float)
        gyro = np.atleast_2d(np.asarray(gyro_fast_dps, dtype=float))
        if self.use_mag and mag_ut is None:
            raise ValueError("the 9DOF filter needs a magnetometer reading")
        mag = np.asarray(mag_ut, dtype=float) if mag_ut is not None else np.zeros(3)

        if not self.initialised:
            self._init_state()
            self.initialised = True
            return self._result(False, np.zeros(3), False)

        if not self.locked:
            self._lock(accel, mag)

        omega = gyro.mean(axis=0) - self.b

        # a priori orientation: integrate each fast gyro sample (quaternions accumulate right)
        q_mi = self.q.copy()
        for y in gyro:
            q_mi = quat_mul(q_mi, quat_from_rotvec_deg((y - self.b) * s.fast_dt_s))
        r_mi = matrix_from_quat(q_mi)

        # gyro-predicted gravity and geomagnetic vectors in the sensor frame
        g_gyro = r_mi[:, 2] if cs is CoordinateSystem.NED else -r_mi[:, 2]
        a_mi = s.accel_decay * self.a_sensor
        g_accel = accel if cs.gravity_positive else -accel
        g_err = g_accel + a_mi - g_gyro
        m_gyro = r_mi @ self.m_global
        m_err = mag - m_gyro

        c = self._measurement_matrix(g_gyro, m_gyro)
        noise_factor = self._accel_distrust(accel, c, g_err, at_rest)
        mag_steers = self._mag_may_steer(noise_factor)
        gated_out = False  # the gate found the field implausible: not the Earth's
        if mag_steers and self._s9().mag_innovation_gate_sigma is not None:
            mag_steers, yaw_deg = self._mag_gate_verdict(c, m_gyro, r_mi, mag)
            gated_out = not mag_steers
            if yaw_deg is not None:  # reacquired: the heading turned to the magnetometer's
                q_mi = quat_mul(quat_about_vertical_deg(-yaw_deg), q_mi)
                r_mi, m_gyro, c = self._magnetic_prediction(q_mi, g_gyro)
                m_err = mag - m_gyro
        k = self._gain(c, noise_factor)

        # a posteriori error vector; d always sees both measurements
        xe = k[:, :3] @ g_err
        jamming = False
        if self.use_mag:
            xe[D] += k[D, 3:] @ m_err
            field = self._field()
            jamming = bool(xe[D] @ xe[D] > 4.0 * field * field)
            if not jamming and mag_steers:
                xe[:9] += k[:9, 3:] @ m_err

        p = self._posterior(k, c)
        if at_rest:
            self._fuse_rest_offset(xe, p, gyro.mean(axis=0))

        # apply the corrections
        q_pl = quat_mul(q_mi, quat_from_rotvec_deg(-xe[TH]))
        self.q = normalise_positive(q_pl)
        self.b = self.b - xe[B]
        self.a_sensor = a_mi - xe[A]
        r_pl = matrix_from_quat(self.q)

        if self.use_mag and not jamming and not gated_out:
            self._track_inclination(r_pl.T @ xe[D])

        self._next_covariance(p)
        return self._result(True, omega, jamming, accel=accel, r_pl=r_pl)

    def _lock(self, accel: FloatArray, mag: FloatArray) -> None:
        """The orientation from the accelerometer's tilt (6DOF) or the eCompass (9DOF, which
        also measures the inclination and the field length the magnetometer gate expects)."""
        cs = self.s.coordinate_system
        if self.use_mag:
            r0, self.inclination_deg = ecompass(cs, accel, mag)
            self.mag_gate[:] = 0.0
            self.mag_gate[GATE_LENGTH] = float(np.linalg.norm(mag))
            if self._s9().lock_sets_inclination:
                self._set_inclination(self.inclination_deg)
        else:
            r0 = tilt_matrix(cs, accel)
        self.q = quat_from_matrix_fsl(r0)
        self.locked = True

    def _accel_distrust(self, accel: FloatArray, c: FloatArray, g_err: FloatArray,
                        at_rest: bool) -> float:
        """The accelerometer noise factor of the soft and innovation gates; 1 at rest (the
        reading is gravity: nothing to gate, and the innovation gate opens)."""
        if at_rest:
            self.gate_closed_s = 0.0
            return 1.0
        noise_factor = self._accel_noise_factor(accel)
        return noise_factor * self._innovation_noise_factor(c, noise_factor, g_err)

    def _magnetic_prediction(self, q_mi: FloatArray, g_gyro: FloatArray
                             ) -> tuple[FloatArray, FloatArray, FloatArray]:
        """For the a priori orientation ``q_mi`` (turned in heading only, so the predicted
        gravity ``g_gyro`` stands): its matrix, the predicted geomagnetic vector (sensor
        frame) and the measurement matrix."""
        r_mi = matrix_from_quat(q_mi)
        m_gyro = r_mi @ self.m_global
        return r_mi, m_gyro, self._measurement_matrix(g_gyro, m_gyro)

    def _measurement_matrix(self, g_gyro: FloatArray, m_gyro: FloatArray) -> FloatArray:
        """C: how the error vector shows in the measurement error (gravity; geomagnetism).

        An orientation error theta (deg) leaves the gyro-predicted sensor-frame vector v off
        by (pi/180) theta x v, so the measured-minus-predicted error picks up
        -(pi/180) [v]x theta. A gyro offset error acts through the orientation error it
        builds over one Kalman interval (-dt times that), linear acceleration adds directly to
        the gravity error and a magnetic disturbance subtracts from the geomagnetic one.
        """
        dt = self.s.kalman_dt_s
        c = np.zeros((6 if self.use_mag else 3, self.n))
        c[0:3, TH] = -DEG * skew(g_gyro)
        c[0:3, B] = dt * DEG * skew(g_gyro)
        c[0:3, A] = np.eye(3)
        if self.use_mag:
            c[3:6, TH] = -DEG * skew(m_gyro)
            c[3:6, B] = dt * DEG * skew(m_gyro)
            c[3:6, D] = -np.eye(3)
        return c

    def _measurement_noise(self) -> FloatArray:
        """Qv: sensor noise plus the process noise the one-step prediction adds (diagonal)."""
        s = self.s
        dt2 = s.kalman_dt_s**2
        gyro_var = s.qw_gyro_offset_dps2 + s.qv_gyro_dps2
        qv_aa = s.qv_accel_g2 + s.qw_accel_g2 + DEG * DEG * dt2 * gyro_var
        if not self.use_mag:
            return np.full(3, qv_aa)
        s9 = self._s9()
        field = s9.field_strength_ut
        qv_mm = s9.qv_mag_ut2 + s9.qw_mag_disturbance_ut2 + DEG * DEG * dt2 * field**2 * gyro_var
        return np.array([qv_aa] * 3 + [qv_mm] * 3)

    def _accel_noise_factor(self, accel_g: FloatArray) -> float:
        """How much less the accelerometer is trusted this step: (1 + (| |a| - 1 | / w)^2)^2
        for the soft gate width w (g), 1 without one (the reference). Accelerations the
        linear-acceleration model cannot follow (a loop, a pull-up, a launch) then move the
        attitude much less."""
        width = self.s.accel_soft_gate_g
        if width is None:
            return 1.0
        return soft_gate_distrust(float(np.linalg.norm(accel_g)), width) ** 2

    def _innovation_noise_factor(self, c: FloatArray, accel_noise_factor: float,
                                 g_err: FloatArray) -> float:
        """How much less the accelerometer is trusted because its innovation is implausible:
        (m / k)^4 while the gravity innovation's Mahalanobis distance m = sqrt(e^T S^-1 e)
        exceeds the gate k (``accel_innovation_gate_sigma``), else 1; always 1 without a gate
        (the reference).

        The filter models linear acceleration as a small, fast-decaying process, so a
        sustained acceleration across gravity that it was not told about (a launch run, a
        turn whose compensation lags) reads as a tilt, and the soft gate hardly sees it: 0.2 g
        sideways is 1.02 g. Fused at full weight it tilts the attitude and, worse, drives the
        gyro offset estimate, which then tilts it for tens of seconds (``thermal``, build
        422's measurement: 2.5 deg/s of pitch offset at the launch). The innovation shows it:
        many standard deviations of S, where the calibrated gyro's own drift stays within a
        few. A gate closed for ``accel_gate_reacquire_s`` without a break is taken to be the
        attitude, not the accelerometer, being wrong (a gyro glitch, a saturated spin): the
        accelerometer is then fused at full weight until the innovation is back within the
        gate, as build 422 would."""
        gate = self.s.accel_innovation_gate_sigma
        if gate is None:
            return 1.0
        noise = self._measurement_noise()[:3] * accel_noise_factor
        s_gg = c[:3] @ self.qw @ c[:3].T + np.diag(noise)
        try:
            m2 = float(g_err @ np.linalg.solve(s_gg, g_err))
        except np.linalg.LinAlgError:
            return 1.0
        ratio2 = m2 / (gate * gate)
        if ratio2 <= 1.0:
            self.gate_closed_s = 0.0
            return 1.0
        self.gate_closed_s += self.s.kalman_dt_s
        if self.gate_closed_s > self.s.accel_gate_reacquire_s:
            return 1.0
        return ratio2 * ratio2

    def _mag_may_steer(self, accel_noise_factor: float) -> bool:
        """Whether the magnetometer may correct orientation and gyro offset this step: not
        while the gates distrust the accelerometer by more than ``mag_max_accel_distrust``
        (9DOF; always without the setting, as in build 422).

        With the accelerometer gated the magnetometer alone would steer the tilt, and the
        offset, through its two axes: any hard-iron residual or nearby magnet then turns
        the attitude (uncalibrated seed board, `rc-flight`: 68 deg tilt RMS; BROAD fast
        rotation, trial 07: 99 deg total). The gyro carries those moments instead."""
        if not self.use_mag:
            return False
        limit = self._s9().mag_max_accel_distrust
        return limit is None or accel_noise_factor <= limit

    def _mag_gate_verdict(self, c: FloatArray, m_gyro: FloatArray, r_mi: FloatArray,
                          mag: FloatArray) -> tuple[bool, float | None]:
        """The magnetometer innovation gate (9DOF with ``mag_innovation_gate_sigma``; build
        422 has none) and its reacquire rule: whether the magnetometer may steer this step,
        and the heading correction (deg, about the global vertical) to apply first when the
        gate reacquires (None: none).

        The gate: the geomagnetic innovation's Mahalanobis distance against the magnetometer
        block of S = C Qw C^T + Qv within ``mag_innovation_gate_sigma``. The filter's
        magnetic model is the Earth's field plus a small, decaying disturbance. An
        uncalibrated magnetometer's hard iron is a body-fixed offset of about a quarter of
        the field, which turns with the board: in turns it reads as a heading and tilt error
        the gyro does not confirm, and fused at full weight it drove the gyro offset
        estimate to 5 deg/s and the tracked inclination to its clamp (uncalibrated seed
        board, `thermal` with the nominal airspeed: 55 deg tilt at 84 s; 6.0 deg with the
        gate). The innovation the gate tests is taken against the predicted field scaled
        to the length the site's field was measured to have (``GATE_LENGTH``: at the lock,
        then following its median, ``FIELD_LENGTH_RATE_UT_S``), not to
        ``field_strength_ut``: the length does not depend on the attitude, and against the
        50 uT default a 42 uT site (BROAD) is 8 uT of innovation at every step, which kept
        the gate shut from the start.

        The reacquire rule: a gate that only closes holds on to a wrong heading for good.
        A disturbance and a wrong heading differ in what they do to the field seen in the
        global frame through the a priori attitude: a wrong heading only turns it about
        the vertical, by the same angle whatever the board does, while a magnet, a hard iron
        or a steel structure changes its length or dip, or turns it differently as the
        board turns. So each rejected step's heading offset psi (the horizontal angle from
        the reference field to the measured one) is added to the stretch's circular mean,
        and the step counts towards reacquiring only if the mean offset explains it: the
        innovation left after turning the reference field by the mean lies within the same
        gate. A stretch of such steps lasting ``mag_gate_reacquire_s`` is the heading being
        wrong: it is turned by the mean offset and the magnetometer steers again. A step the
        mean does not explain ends the stretch. (A field that looks like the Earth's turned
        in heading for longer than the reacquire time cannot be told from a heading
        error.)"""
        s9 = self._s9()
        gate = s9.mag_innovation_gate_sigma
        assert gate is not None
        state = self.mag_gate
        length = state[GATE_LENGTH]
        state[GATE_LENGTH] += _towards(float(np.linalg.norm(mag)) - length,
                                       FIELD_LENGTH_RATE_UT_S * self.s.kalman_dt_s)
        s_mm = c[3:] @ self.qw @ c[3:].T + np.diag(self._measurement_noise()[3:])
        m2 = _mahalanobis2(s_mm, _innovation_at_length(mag, m_gyro, length))
        if m2 is None or m2 <= gate * gate:
            state[:GATE_LENGTH] = 0.0
            return True, None
        reacquire_s = s9.mag_gate_reacquire_s
        if reacquire_s is None:
            return False, None
        # this step's heading offset: the measured field in the global frame against the
        # reference's horizontal direction
        m_g = r_mi.T @ mag
        ref = self.m_global
        psi = math.atan2(ref[0] * m_g[1] - ref[1] * m_g[0], ref[0] * m_g[0] + ref[1] * m_g[1])
        state[GATE_COS] += math.cos(psi)
        state[GATE_SIN] += math.sin(psi)
        mean = math.atan2(state[GATE_SIN], state[GATE_COS])
        turned = r_mi @ (_about_vertical(mean) @ ref)
        m2_turned = _mahalanobis2(s_mm, _innovation_at_length(mag, turned, length))
        if m2_turned is None or m2_turned > gate * gate:
            state[:GATE_LENGTH] = 0.0  # not a heading error alone: the stretch ends
            return False, None
        state[GATE_CLOSED] += self.s.kalman_dt_s
        if state[GATE_CLOSED] < reacquire_s:
            return False, None
        state[:GATE_LENGTH] = 0.0
        return True, math.degrees(mean)

    def _gain(self, c: FloatArray, accel_noise_factor: float = 1.0) -> FloatArray:
        """K = Qw C^T S^-1 with S = C Qw C^T + Qv (Qw stands in for the a priori P)."""
        qw_ct = self.qw @ c.T
        noise = self._measurement_noise()
        noise[:3] *= accel_noise_factor
        innov = c @ qw_ct + np.diag(noise)
        innov = np.triu(innov) + np.triu(innov, 1).T  # the reference fills S from its top half
        if self.use_mag and not self._s9().full_innovation_inverse:
            # build 422: only the gravity block is inverted in place; the rest stays S
            inv = innov.copy()
            inv[:3, :3] = _inverse_or_identity(innov[:3, :3])
        else:
            inv = _inverse_or_identity(innov)
        return qw_ct @ inv

    def _set_inclination(self, inclination_deg: float) -> None:
        """Point the reference geomagnetic vector at ``inclination_deg`` (clamped), length B."""
        s9 = self._s9()
        lim = s9.max_inclination_deg
        d = math.radians(max(-lim, min(lim, inclination_deg)))
        ned = s9.coordinate_system is CoordinateSystem.NED
        north, sign_down = (0, 1.0) if ned else (1, -1.0)
        self.inclination_deg = math.degrees(d)
        self.m_global[:] = 0.0
        self.m_global[north] = s9.field_strength_ut * math.cos(d)
        self.m_global[2] = sign_down * s9.field_strength_ut * math.sin(d)

    def _track_inclination(self, d_global: FloatArray) -> None:
        """Rotate the reference geomagnetic vector towards the observed disturbance, keeping
        its length B and its north component non-negative, the dip within +-max inclination."""
        s9 = self._s9()
        ned = s9.coordinate_system is CoordinateSystem.NED
        north, sign_down = (0, 1.0) if ned else (1, -1.0)
        down = sign_down * (self.m_global[2] - d_global[2])
        horiz = max(self.m_global[north] - d_global[north], 0.0)
        hyp = math.hypot(down, horiz)
        if hyp == 0.0:
            return
        sin_d, cos_d = down / hyp, horiz / hyp
        lim = math.radians(s9.max_inclination_deg)
        if abs(sin_d) > math.sin(lim):
            sin_d, cos_d = math.copysign(math.sin(lim), sin_d), math.cos(lim)
        self.inclination_deg = math.degrees(math.asin(max(-1.0, min(1.0, sin_d))))
        self.m_global[north] = s9.field_strength_ut * cos_d
        self.m_global[2] = sign_down * s9.field_strength_ut * sin_d

    def _posterior(self, k: FloatArray, c: FloatArray) -> FloatArray:
        """P+ = Qw - K C Qw (upper triangle, mirrored as the reference does)."""
        full = self.qw - k @ (c @ self.qw)
        return np.triu(full) + np.triu(full, 1).T

    def _fuse_rest_offset(self, xe: FloatArray, p: FloatArray, gyro_mean_dps: FloatArray
                          ) -> None:
        """At rest the gyro measures its offset alone: the window's mean reading z (deg/s,
        sensor axes) is a measurement of the offset state, fused after the accelerometer
        (and magnetometer) update as a second, sequential Kalman update. ``xe`` (the error
        vector so far) and ``p`` (its covariance P+) are updated in place.

        The offset estimate after the first update is b - xe_b; it exceeds z by
        e = b - xe_b - z, which measures the remaining offset error with the noise of a
        window's mean rate, ``qv_gyro_dps2`` (the variance the filter's own prediction gives
        that mean). The gain K = P+ H^T (H P+ H^T + R)^-1 with H picking the offset block
        spreads the correction over every state through P+'s correlations: the orientation
        error the offset has built up is taken back with it (an offset error of known size
        since the last lock turned the attitude by a known amount)."""
        e = self.b - xe[B] - gyro_mean_dps
        s_bb = p[B, B] + self.s.qv_gyro_dps2 * np.eye(3)
        gain = p[:, B] @ _inverse_or_identity(s_bb)
        xe += gain @ e
        full = p - gain @ p[B, :]
        p[:] = np.triu(full) + np.triu(full, 1).T

    def _next_covariance(self, p: FloatArray) -> None:
        """The next Qw from the a posteriori P+'s diagonal: the offset random walk feeds the
        orientation error over dt."""
        s = self.s
        dt = s.kalman_dt_s
        qw = np.zeros_like(self.qw)
        for i in range(3):
            qw[3 + i, 3 + i] = p[3 + i, 3 + i] + s.qw_gyro_offset_dps2
            qw[i, i] = p[i, i] + dt * dt * (p[3 + i, 3 + i] + s.qw_gyro_offset_dps2
                                             + s.qv_gyro_dps2)
            qw[i, 3 + i] = qw[3 + i, i] = -dt * qw[3 + i, 3 + i]
            qw[6 + i, 6 + i] = s.accel_decay**2 * p[6 + i, 6 + i] + s.qw_accel_g2
            if self.use_mag:
                s9 = self._s9()
                qw[9 + i, 9 + i] = (s9.disturbance_decay**2 * p[9 + i, 9 + i]
                                    + s9.qw_mag_disturbance_ut2)
        self.qw = qw

    def _result(self, valid: bool, omega: FloatArray, jamming: bool, *,
                accel: FloatArray | None = None, r_pl: FloatArray | None = None) -> KalmanStep:
        cs = self.s.coordinate_system
        r = matrix_from_quat(self.q) if r_pl is None else r_pl
        lin = np.zeros(3)
        if accel is not None:
            lin = r.T @ accel
            if cs is CoordinateSystem.NED:
                lin = -(lin - np.array([0.0, 0.0, 1.0]))
            elif cs is CoordinateSystem.ANDROID:
                lin = lin - np.array([0.0, 0.0, 1.0])
            else:
                lin = -(lin + np.array([0.0, 0.0, 1.0]))
        euler = (euler_angles_deg(cs, r) if valid
                 else {"phi": 0.0, "theta": 0.0, "psi": 0.0, "rho": 0.0, "chi": 0.0})
        return KalmanStep(
            valid=valid, q_sensor_to_global=self.q.copy(), euler_deg=euler,
            gyro_offset_dps=self.b.copy(), omega_dps=np.asarray(omega, dtype=float).copy(),
            linear_accel_sensor_g=self.a_sensor.copy(), linear_accel_global_g=lin,
            inclination_deg=self.inclination_deg, mag_jamming=jamming,
        )


def _mahalanobis2(s: FloatArray, e: FloatArray) -> float | None:
    """e^T S^-1 e; None when S is singular (no gate then)."""
    try:
        return float(e @ np.linalg.solve(s, e))
    except np.linalg.LinAlgError:
        return None


def _towards(difference: float, step: float) -> float:
    """``step`` in the direction of ``difference`` (0 when it is 0)."""
    if difference > 0.0:
        return step
    return -step if difference < 0.0 else 0.0


def _innovation_at_length(mag: FloatArray, predicted: FloatArray, length: float
                          ) -> FloatArray:
    """``mag`` minus ``predicted`` scaled to ``length`` (unscaled if it is zero)."""
    n = float(np.linalg.norm(predicted))
    return mag - predicted if n == 0.0 else mag - (length / n) * predicted


def _about_vertical(angle_rad: float) -> FloatArray:
    """The rotation matrix by ``angle_rad`` about the global z axis (right-handed; the
    vertical of every coordinate system)."""
    co, si = math.cos(angle_rad), math.sin(angle_rad)
    return np.array([[co, -si, 0.0], [si, co, 0.0], [0.0, 0.0, 1.0]])


def quat_about_vertical_deg(angle_deg: float) -> FloatArray:
    """The quaternion of a turn by ``angle_deg`` about the global z axis (right-handed);
    multiplied on the left of a sensor -> global quaternion it turns the global side."""
    half = math.radians(angle_deg) / 2.0
    return np.array([math.cos(half), 0.0, 0.0, math.sin(half)])


def _inverse_or_identity(m: FloatArray) -> FloatArray:
    """Inverse of ``m``; identity if singular (what the reference's Gauss-Jordan returns)."""
    try:
        inverse: FloatArray = np.linalg.inv(m)  # type: ignore[assignment]  # numpy's stubs type inv() as floating[Any]; float64 in, float64 out
        return inverse
    except np.linalg.LinAlgError:
        return np.eye(m.shape[0])
