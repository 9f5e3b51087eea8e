"""The per-sample kernel of the "decoupled" estimator, on plain floats.

The method follows Laidig and Seel, "VQF: Highly Accurate IMU Orientation Estimation with Bias
Estimation and Magnetic Disturbance Rejection" (Information Fusion 91, 2023), in imuhal's own
form. The attitude is the product of three parts, body -> NED::

    q = q_heading(delta) * q_inclination * q_gyro

- ``q_gyro`` integrates the bias-corrected gyro (strapdown) from the aligned start into an
  almost-inertial frame I (it drifts only by the residual gyro bias);
- the accelerometer (gravity positive, in g) is rotated into I and low-pass filtered there
  (second-order Butterworth, mean delay ``tau_acc_s``; slowed for readings away from 1 g,
  ``accel_soft_gate_g``, and sped up at rest, ``tau_acc_rest_s``): in an inertial frame the
  kinematic acceleration integrates to a velocity change, so over seconds it averages out
  and what remains is gravity. The
  inclination correction ``q_inclination`` then turns the filtered vector to the vertical each
  step; all smoothing is in the filter, so a transient linear acceleration barely tilts it;
- the heading is a separate angle ``delta`` about the NED vertical, pulled towards the
  magnetometer's horizontal direction with time constant ``tau_mag_s``; it never touches the
  inclination. The field's norm and dip are compared with a reference; a reading off by more
  than ``mag_norm_th`` (relative) or ``mag_dip_th_deg`` is a disturbance and is not fused. A
  new field that stays consistent for ``mag_new_s`` (e.g. moving to another room) becomes the
  reference;
- the gyro bias is a Kalman filter (``bias.py``): at rest (gyro and accelerometer both steady
  for ``rest_min_s``, gyro slower than the bias clip) the low-passed gyro measures it; in
  motion the inclination correction does (a bias error turns the strapdown, the
  accelerometer turns it back: the correction rate is the bias seen in the earth frame);
- a vehicle's manoeuvre (a take-off push, a loop, a banked turn without a speed source) does
  not average out within ``tau_acc_s``; what no hand does, the manoeuvre detector
  (common/innovation.py, ``ManoeuvreDetector``: the innovation's leaky velocity and its
  steadiness) sees, and the filter then holds still. The detector needs a few tenths of a
  second to decide, so the filter input of the last ``lookback_s`` is kept, with the filter
  as it was before it: when the weight drops below one half, that stretch is filtered again
  with the new weight (delaying the filter's input instead, so the detector always looks
  ahead, costs hand-held motion: BROAD trial 15 6-DOF inclination 0.47 -> 0.76 deg at 0.5 s);
  and when the velocity change of what it withheld comes back (a hand's stroke, which the
  steadiness statistic can take for a push at first), it is all filtered again in full
  (``lookback.py``);
- in straight flight through turbulence (``turbulence.py``), which keeps a soft gate closed,
  the filtered accelerometer is also turned towards each reading at a capped rate
  (``turbulence_rate_rad_s``), so the gyro error of a manoeuvre is walked back as madgwick
  walks it back.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from imuhal.core.atmosphere import STANDARD_GRAVITY_M_S2
from imuhal_filters.common.gate import soft_gate_weight
from imuhal_filters.common.innovation import InnovationSpeed, ManoeuvreDetector, ManoeuvreParams
from imuhal_filters.common.quat import IDENTITY, Quat, Vec, multiply, to_global
from imuhal_filters.decoupled.bias import BiasParams, GyroBiasKalman
from imuhal_filters.decoupled.butterworth import ButterworthLowPass
from imuhal_filters.decoupled.lookback import LookBack
from imuhal_filters.decoupled.pace import RotationPace
from imuhal_filters.decoupled.turbulence import StraightFlightDetector, TurbulenceParams


@dataclass(frozen=True, slots=True)
class DecoupledParams:
    """The kernel's constants (seconds, rad/s, g; see the module docstring)."""

    tau_acc_s: float = 3.0
    tau_acc_rest_s: float | None = None
    tau_mag_s: float = 9.0
    accel_soft_gate_g: float | None = None
    innovation_speed_m_s: float | None = None
    innovation_tau_s: float = 1.0
    manoeuvre: ManoeuvreParams | None = None
    lookback_s: float = 0.5
    gyro_relative_error: float | None = None
    rest_gyro_th_rad_s: float = math.radians(2.0)
    rest_acc_th_g: float = 0.05
    rest_filter_tau_s: float = 0.5
    rest_min_s: float = 1.5
    bias_clip_rad_s: float = math.radians(2.0)
    bias: BiasParams = field(default_factory=BiasParams)
    mag_norm_th: float = 0.1
    mag_dip_th_deg: float = 10.0
    mag_ref_tau_s: float = 20.0
    mag_new_s: float = 20.0
    turbulence_rate_rad_s: float | None = None
    turbulence: TurbulenceParams = field(default_factory=TurbulenceParams)


def _rotvec_quat(x: float, y: float, z: float) -> Quat:
    """Quaternion of the rotation vector (x, y, z) (rad)."""
    a = math.sqrt(x * x + y * y + z * z)
    if a < 1e-12:
        return (1.0, 0.5 * x, 0.5 * y, 0.5 * z)
    s = math.sin(0.5 * a) / a
    return (math.cos(0.5 * a), x * s, y * s, z * s)


def _unit_quat(q: Quat) -> Quat:
    n = 1.0 / math.sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3])
    return (q[0] * n, q[1] * n, q[2] * n, q[3] * n)


def rotation_rows(q: Quat) -> tuple[float, ...]:
    """The rotation matrix of ``q`` (local -> global), row by row (9 values)."""
    w, x, y, z = q
    return (1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y),
            2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x),
            2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y))


def inclination_correction(q_inc: Quat, e: Vec) -> tuple[Quat, Vec]:
    """Turn ``q_inc`` so the filtered accelerometer ``e`` (already in the frame after q_inc)
    points up: returns the new q_inc and the correction's rotation vector (rad)."""
    ex, ey, ez = e
    n = math.sqrt(ex * ex + ey * ey + ez * ez)
    if n < 1e-9:
        return q_inc, (0.0, 0.0, 0.0)
    ex, ey, ez = ex / n, ey / n, ez / n
    # rotation taking e to up: axis e x up = (ey, -ex, 0), angle acos(ez)
    s = math.hypot(ex, ey)
    if s < 1e-12:
        return q_inc, (0.0, 0.0, 0.0)
    angle = math.atan2(s, ez)
    rx, ry = ey / s * angle, -ex / s * angle
    return _unit_quat(multiply(_rotvec_quat(rx, ry, 0.0), q_inc)), (rx, ry, 0.0)


def turn_state_towards(filt: ButterworthLowPass, target: Vec, max_angle_rad: float
                       ) -> tuple[float, ...]:
    """Turn a 3-vector filter's state (value and rate alike, so it keeps filtering from the
    turned value) by at most ``max_angle_rad`` towards the direction of ``target``; returns
    the new value."""
    st = filt.state
    assert st is not None
    fx, fy, fz = st[0], st[1], st[2]
    tx, ty, tz = target
    cx, cy, cz = fy * tz - fz * ty, fz * tx - fx * tz, fx * ty - fy * tx
    s = math.sqrt(cx * cx + cy * cy + cz * cz)
    if s < 1e-15 or max_angle_rad <= 0.0:
        return (fx, fy, fz)
    angle = min(math.atan2(s, fx * tx + fy * ty + fz * tz), max_angle_rad) / s
    r = rotation_rows(_rotvec_quat(cx * angle, cy * angle, cz * angle))
    for k in (0, 3):
        x, y, z = st[k], st[k + 1], st[k + 2]
        st[k] = r[0] * x + r[1] * y + r[2] * z
        st[k + 1] = r[3] * x + r[4] * y + r[5] * z
        st[k + 2] = r[6] * x + r[7] * y + r[8] * z
    return (st[0], st[1], st[2])


def follow(held: Vec | None, x: Vec, k: float) -> Vec:
    """A first-order low-pass one step of weight ``k`` from ``held`` toward ``x``; its first
    input (``held`` None) starts it (the rest detector's gyro and accelerometer filters)."""
    if held is None:
        return x
    return (held[0] + k * (x[0] - held[0]), held[1] + k * (x[1] - held[1]),
            held[2] + k * (x[2] - held[2]))


def _wrap(a: float) -> float:
    return (a + math.pi) % (2.0 * math.pi) - math.pi


class DecoupledKernel:
    """State and one step of the filter. ``start(q)`` sets the aligned attitude."""

    def __init__(self, params: DecoupledParams) -> None:
        self.p = params
        self.start(IDENTITY)

    def start(self, q: Quat, bias: Vec = (0.0, 0.0, 0.0)) -> None:
        self.q_gyro: Quat = q
        self.q_inc: Quat = IDENTITY
        self.delta_rad = 0.0
        self.acc_i: Vec | None = None
        self._acc_filter = ButterworthLowPass(self.p.tau_acc_s)
        # the motion bias model low-passes R and R b exactly as the accelerometer
        self._r_filter = ButterworthLowPass(self.p.tau_acc_s)
        self._rb_filter = ButterworthLowPass(self.p.tau_acc_s)
        self.kf = GyroBiasKalman(self.p.bias, bias)
        self.straight = StraightFlightDetector(self.p.turbulence)
        self.innovation = None if self.p.innovation_speed_m_s is None else InnovationSpeed(
            self.p.innovation_tau_s, self.p.innovation_speed_m_s, self.p.tau_acc_s)
        self.manoeuvre = None if self.p.manoeuvre is None else ManoeuvreDetector(
            self.p.manoeuvre)
        m = self.p.manoeuvre
        self.lookback = None if m is None else LookBack(
            self.p.tau_acc_s, self.p.lookback_s, m.leak_s, m.speed_m_s,
            m.floor_m_s2 * m.window_s)
        eps = self.p.gyro_relative_error
        self.pace = None if eps is None else RotationPace(
            self.p.tau_acc_s, eps, ManoeuvreParams().floor_m_s2 if m is None else m.floor_m_s2)
        self.gyro_lp: Vec | None = None
        self.acc_lp: Vec | None = None
        self.rest_s = 0.0
        self.mag_ref: tuple[float, float] | None = None
        self.mag_cand: tuple[float, float] | None = None
        self.mag_cand_s = 0.0
        self.mag_disturbed = False
        self.accel_missed = False
        """A step since the last accelerometer reading had none (``_after_accel_gap``)."""

    def reseat(self, q: Quat) -> None:
        """Start the attitude again at ``q`` (body -> NED; the angular-rate recovery's
        re-seat from the accelerometer): the strapdown, the inclination filter and the
        detectors as at ``start``, since what they held was seen through the attitude the
        clip corrupted; kept: the gyro bias with its uncertainty and the magnetometer's
        reference field (properties of the sensor and the place, not of the attitude)."""
        kf = self.kf
        mag = (self.mag_ref, self.mag_cand, self.mag_cand_s, self.mag_disturbed)
        self.start(q, kf.b)
        self.kf = kf
        self.mag_ref, self.mag_cand, self.mag_cand_s, self.mag_disturbed = mag

    @property
    def bias(self) -> Vec:
        """The gyro bias estimate (body, rad/s)."""
        return self.kf.b

    @property
    def rest(self) -> bool:
        return self.rest_s >= self.p.rest_min_s

    def quaternion(self) -> Quat:
        half = 0.5 * self.delta_rad
        qh = (math.cos(half), 0.0, 0.0, math.sin(half))
        return multiply(qh, multiply(self.q_inc, self.q_gyro))

    # ------------------------------------------------------------------ step
    def step(self, gyro: Vec, acc_g: Vec | None, mag: Vec | None, dt: float) -> Quat:
        """One gyro sample (rad/s), the latest accelerometer (gravity positive, g) and
        magnetometer (any unit) or None; returns the body -> NED quaternion."""
        bx, by, bz = self.kf.b
        wx, wy, wz = gyro[0] - bx, gyro[1] - by, gyro[2] - bz
        self.q_gyro = _unit_quat(multiply(self.q_gyro, _rotvec_quat(wx * dt, wy * dt, wz * dt)))
        if acc_g is None:
            self.accel_missed = True
        elif self.accel_missed:
            self._after_accel_gap()
        self._rest_step(gyro, acc_g, dt)
        if acc_g is not None:
            if self.p.turbulence_rate_rad_s is not None:
                up_rate = to_global(multiply(self.q_inc, self.q_gyro), (wx, wy, wz))[2]
                self.straight.step(acc_g, up_rate, dt)
            corr, dt_filter = self._inclination_step(acc_g, dt, (wx, wy, wz))
            self._bias_step(corr, dt, dt_filter)
        if mag is not None:
            self._heading_step(mag, dt)
        return self.quaternion()

    def _after_accel_gap(self) -> None:
        """The first accelerometer reading after steps without one (the reading flagged,
        lost or stale: ``max_aux_age_s``): the detectors that judge the readings by their
        recent past start again, as at start-up, since what the board did meanwhile was not
        measured. Their memory of before the gap is stale: a pull-up the manoeuvre detector
        was seeing when the accelerometer clipped had, 0.4-1 s later, a window of readings
        long gone, so it weighted the readings after the gap as a hand's (``rc-flight`` on
        the seed board, its clipped pull-ups: tilt RMS 2.68 deg with that memory, 1.84
        started again; docs/estimators.md). The detector's velocity is kept in half
        (``ManoeuvreDetector.restart``: zeroed, it declared the clipping board at rest and
        the GY-91's ``rc-flight`` went from 2.09 to 3.25 deg; halved, 1.69).

        Rest, too, is declared anew: ``rest_min_s`` with both sensors steady, and the
        accelerometer was not read (a steady push without rotation, counted on across a
        0.5 s gap by the gyro alone, was rest 1 s after it and fused in full).

        Kept: the filters (their state is the attitude, in the almost-inertial frame the
        gyro carried across the gap), the bias, the heading and the tilt-error drift; and
        the look-back's kept readings, measurements still, which the detector's decision
        after the gap may re-weight. Its episode ends: its velocity change across the gap
        is unknown, so whether it came back cannot be told."""
        self.accel_missed = False
        self.acc_lp = None
        self.rest_s = 0.0
        if self.manoeuvre is not None:
            self.manoeuvre.restart()
        if self.innovation is not None:
            self.innovation.reset()
        if self.pace is not None:
            self.pace.started = False
        if self.lookback is not None:
            self.lookback.episode_s = None
        self.straight = StraightFlightDetector(self.p.turbulence)

    def _rest_step(self, gyro: Vec, acc_g: Vec | None, dt: float) -> None:
        p = self.p
        k = 1.0 - math.exp(-dt / p.rest_filter_tau_s)
        self.gyro_lp = g = follow(self.gyro_lp, gyro, k)
        still = (sum((gyro[i] - g[i]) ** 2 for i in range(3)) < p.rest_gyro_th_rad_s ** 2
                 and max(abs(g[0]), abs(g[1]), abs(g[2])) < p.bias_clip_rad_s)
        if acc_g is not None:
            self.acc_lp = a = follow(self.acc_lp, acc_g, k)
            still = still and sum((acc_g[i] - a[i]) ** 2 for i in range(3)) < p.rest_acc_th_g ** 2
        self.rest_s = self.rest_s + dt if still else 0.0

    def _bias_step(self, corr: Vec, dt: float, dt_filter: float) -> None:
        """One Kalman step of the gyro bias after an inclination correction ``corr`` (rad,
        earth frame) made over ``dt`` s, the accelerometer filter having advanced by
        ``dt_filter`` s (bias.py states the model)."""
        kf = self.kf
        r = rotation_rows(multiply(self.q_inc, self.q_gyro))
        b = kf.b
        rb = (r[0] * b[0] + r[1] * b[1] + r[2] * b[2], r[3] * b[0] + r[4] * b[1] + r[5] * b[2])
        h = self._r_filter.step(r, dt_filter)
        rb_lp = self._rb_filter.step(rb, dt_filter)
        if dt <= 0.0:
            return
        kf.predict(dt)
        if self.rest:
            assert self.gyro_lp is not None
            kf.rest_update(self.gyro_lp, dt)
            return
        if self.p.bias.sigma_motion_deg_s is None:
            return
        hb = (h[0] * b[0] + h[1] * b[1] + h[2] * b[2], h[3] * b[0] + h[4] * b[1] + h[5] * b[2],
              h[6] * b[0] + h[7] * b[1] + h[8] * b[2])
        e = (-corr[0] / dt + rb_lp[0] - hb[0], -corr[1] / dt + rb_lp[1] - hb[1], -hb[2])
        kf.motion_update(e, [list(h[0:3]), list(h[3:6]), list(h[6:9])], dt)

    def _innovation_m_s2(self, a: Vec) -> Vec:
        """The reading ``a`` (g, almost-inertial frame) minus the filter's gravity (m/s^2;
        zero before the filter has one)."""
        f = self.acc_i
        if f is None:
            return (0.0, 0.0, 0.0)
        g = STANDARD_GRAVITY_M_S2
        return (g * (a[0] - f[0]), g * (a[1] - f[1]), g * (a[2] - f[2]))

    def _inclination_step(self, acc_g: Vec, dt: float, gyro_rad_s: Vec) -> tuple[Vec, float]:
        """Low-pass the accelerometer in I, turn q_inc so it points up (``gyro_rad_s``: the
        bias-corrected gyro); returns the correction's rotation vector (rad) in the
        frame after q_inc and the step the filter advanced by (s)."""
        a = to_global(self.q_gyro, acc_g)
        # the strapdown's error grows with the rotation, the accelerometer's with the
        # acceleration: the filter runs faster when the first dominates (pace.py)
        pace = 1.0 if self.pace is None else self.pace.step(a, self.acc_i, gyro_rad_s, dt)
        # a reading away from 1 g carries kinematic acceleration the turn compensation did
        # not remove (a sustained turn does not average out within tau): the filter advances
        # by only the weight's share of the step (it holds still for a zero weight; feeding
        # it its own estimate instead would close a loop around the second-order filter)
        weight = soft_gate_weight(acc_g, self.p.accel_soft_gate_g)
        if self.innovation is not None:
            if self.rest:
                self.innovation.reset()
            weight *= self.innovation.weight(a, self.acc_i, dt)
        if self.manoeuvre is not None and self.lookback is not None:
            if self.rest:
                self.manoeuvre.reset()
            base = weight
            innovation = self._innovation_m_s2(a)
            # a decision, as vqf's preprocessing takes it: a hand's reading counts in full
            # (the detector's weight just under 1 near its bounds would weight the hand's
            # phases unevenly: BROAD trial 18 0.66 against 0.61 deg), a manoeuvre's by the
            # detector's small weight
            mw = self.manoeuvre.weight(a, self.acc_i, dt)
            if mw < 0.5:
                weight *= mw
            drift = self.manoeuvre.drift_m_s2
            weight, replaced = self.lookback.step(
                self._acc_filter, a, dt, weight, base,
                (innovation[0] - drift[0], innovation[1] - drift[1], innovation[2] - drift[2]),
                self.rest, pace)
            if replaced:
                st = self._acc_filter.state
                assert st is not None
                self.acc_i = (st[0], st[1], st[2])
                self.q_inc, _ = inclination_correction(self.q_inc,
                                                       to_global(self.q_inc, self.acc_i))
        dt_filter = dt * weight * pace
        if self.p.tau_acc_rest_s is not None and self.rest:
            # at rest the specific force is gravity alone: what is left to correct is gyro
            # drift, so the filter may run faster (time scaled: the same filter, shorter tau)
            dt_filter *= self.p.tau_acc_s / self.p.tau_acc_rest_s
        f = self._acc_filter.step(a, dt_filter)
        rate = self.p.turbulence_rate_rad_s
        if rate is not None and self.straight.steady:
            # the gate's closed share, at a capped rate towards this reading: the gusts'
            # scatter averages out, the gyro error does not (turbulence.py); the turn reaches
            # the bias filter as part of the correction (keeping it out changed nothing
            # measurable in the flight benchmark)
            f = turn_state_towards(self._acc_filter, a, rate * dt * (1.0 - weight))
        self.acc_i = (f[0], f[1], f[2])
        self.q_inc, corr = inclination_correction(self.q_inc, to_global(self.q_inc, self.acc_i))
        return corr, dt_filter

    def _heading_step(self, mag: Vec, dt: float) -> float:
        """Check the field against the reference, correct delta; returns the correction (rad)."""
        p = self.p
        mx, my, mz = to_global(multiply(self.q_inc, self.q_gyro), mag)
        norm = math.sqrt(mx * mx + my * my + mz * mz)
        horizontal = math.hypot(mx, my)
        if norm < 1e-9 or horizontal < 1e-3 * norm:
            return 0.0
        dip = math.atan2(mz, horizontal)
        ref = self.mag_ref
        if ref is None:
            self.mag_ref = ref = (norm, dip)
        ok = (abs(norm - ref[0]) < p.mag_norm_th * ref[0]
              and abs(dip - ref[1]) < math.radians(p.mag_dip_th_deg))
        self.mag_disturbed = not ok
        if not ok:
            self._track_candidate(norm, dip, dt)
            return 0.0
        self.mag_cand, self.mag_cand_s = None, 0.0
        kr = 1.0 - math.exp(-dt / p.mag_ref_tau_s)
        self.mag_ref = (ref[0] + kr * (norm - ref[0]), ref[1] + kr * (dip - ref[1]))
        err = _wrap(math.atan2(my, mx) + self.delta_rad)
        dz = -(1.0 - math.exp(-dt / p.tau_mag_s)) * err
        self.delta_rad = _wrap(self.delta_rad + dz)
        return dz

    def _track_candidate(self, norm: float, dip: float, dt: float) -> None:
        """A disturbed field that stays the same for ``mag_new_s`` becomes the reference."""
        p = self.p
        c = self.mag_cand
        if c is None or not (abs(norm - c[0]) < p.mag_norm_th * c[0]
                             and abs(dip - c[1]) < math.radians(p.mag_dip_th_deg)):
            self.mag_cand, self.mag_cand_s = (norm, dip), 0.0
            return
        k = 1.0 - math.exp(-dt / 1.0)
        self.mag_cand = (c[0] + k * (norm - c[0]), c[1] + k * (dip - c[1]))
        self.mag_cand_s += dt
        if self.mag_cand_s >= p.mag_new_s:
            self.mag_ref, self.mag_cand, self.mag_cand_s = self.mag_cand, None, 0.0
