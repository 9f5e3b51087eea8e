"""The seed's 3-state variometer Kalman filter, in the seed's native units (cm, cm/s, cm/s^2).

State ``x = [z, v, b]``: altitude (cm, up +), climb rate (cm/s, up +) and accelerometer bias
(cm/s^2; true vertical acceleration = measured - b). Nair (2016), "IMU modules, AHRS and a
Kalman filter for sensor fusion":

    F = [[1, dt, -dt^2/2], [0, 1, -dt], [0, 0, 1]],   input a_meas enters like the bias, + sign
    Q = [[dt^4/4 sa2, dt^3/2 sa2, 0], [dt^3/2 sa2, dt^2 sa2, 0], [0, 0, sb2]]
    H = [1, 0, 0],  R = sz2

where sz2 = sigma_zmeas^2 (baro altitude noise, cm^2), sa2 = sigma_acc^2 (environment
acceleration, (cm/s^2)^2) and sb2 = sigma_accbias^2 (bias random walk per step, (cm/s^2)^2;
the references add it once per step, not scaled by dt, so its effect depends on the rate).

Tuning, from the seed:

- sigma_zmeas^2: the variance of 1-2 s of barometric altitude at rest at the normal sampling
  rate (see ``estimate_altitude_variance``); longer windows include real pressure drift.
- sigma_acc^2 is the variance of the acceleration the *air and pilot* impose (thermals, sink,
  turbulence); it is NOT the accelerometer noise variance. Larger values make the filter
  follow acceleration inputs faster, smaller ones damp it. Start with sigma_acc^2 numerically
  about equal to sigma_zmeas^2 in cm units (the ratio is the same in m units), then tune to
  taste and to the day's conditions. (The seed author's later ESP32 firmware ships 300 / 50000.)
- A sigma_zmeas^2 smaller than the real baro noise responds faster to pressure changes with
  more jitter; larger values damp the response.
- sigma_accbias^2 small (e.g. 1.0) enforces a slowly drifting bias. The price is a longer
  start-up: the bias takes seconds to converge, and a variometer beeps at rest meanwhile.

Reference modes (``Kf3Mode``), each reproducing one public implementation of the seed author
row by row (float64 here, float32 there: within 0.1 cm and 0.5 cm/s on the conformance data):

- ``esp32`` (default): ESP32_IMU_BARO_GPS_VARIO ``kalmanfilter3`` configure/update API.
  Defaults 300 / 50000 / 1.0, P0 = diag(1, 1, 1e5). Semi-implicit prediction exactly as the
  seed's step 2 writes it: v += (a - b) dt first, then z += v dt with the new v. The default
  because it is the seed's equations without additions: the configured sigma_acc^2 is what the
  filter uses, so the seed's tuning advice applies.
- ``avario``: Kalmanfilter_altimeter_vario ``KalmanFilter``. Same equations, defaults
  200 / 100 / 1.0, but every step replaces sigma_acc^2 with clamp(|a - b| / 50, 1, 50)
  (cm/s^2 in, (cm/s^2)^2 out), so the configured value is never used. More accurate on the
  conformance flight (10 cm/s vs 21 cm/s climb RMS) but its tuning knob is dead.
- ``y2021``: ESP32_IMU_BARO_GPS_VARIO offline/kf ``kalmanfilter3`` (2021). Separate
  predict(a, dt) / update(z) calls, explicit prediction (z += v dt with the old v, then
  v += (a - b) dt), defaults 200 / 100000 / 0.005, P0 = diag(1500, 1500, 1500).
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import Enum

import numpy as np


class Kf3Mode(str, Enum):
    ESP32 = "esp32"
    AVARIO = "avario"
    Y2021 = "y2021"


@dataclass(frozen=True)
class Kf3Reference:
    """One reference implementation: its default tuning and its prediction variant."""

    z_meas_variance: float
    """sigma_zmeas^2, cm^2."""
    accel_variance: float
    """sigma_acc^2, (cm/s^2)^2."""
    bias_variance: float
    """sigma_accbias^2 per step, (cm/s^2)^2."""
    p0_diag: tuple[float, float, float]
    """Initial covariance diagonal (cm^2, (cm/s)^2, (cm/s^2)^2); off-diagonal terms are 0."""
    semi_implicit: bool
    """True: v is advanced first and z uses the new v. False: z uses the old v."""
    adaptive_accel_variance: bool
    """True: sigma_acc^2 = clamp(|a - b| / 50, 1, 50) each step (the avario firmware)."""


REFERENCES: dict[Kf3Mode, Kf3Reference] = {
    Kf3Mode.ESP32: Kf3Reference(300.0, 50_000.0, 1.0, (1.0, 1.0, 100_000.0), True, False),
    Kf3Mode.AVARIO: Kf3Reference(200.0, 100.0, 1.0, (1.0, 1.0, 100_000.0), True, True),
    Kf3Mode.Y2021: Kf3Reference(200.0, 100_000.0, 0.005, (1500.0, 1500.0, 1500.0), False, False),
}

AVARIO_ACCEL_VARIANCE_DIVISOR = 50.0
AVARIO_ACCEL_VARIANCE_RANGE = (1.0, 50.0)


class Kalman3:
    """Altitude / climb rate / accelerometer-bias Kalman filter in cm, cm/s, cm/s^2.

    Call ``configure`` once, then ``predict(a_meas, dt)`` and ``update(z_meas)`` for every
    barometer sample (``step`` does both, as the references' single update call does).
    """

    def __init__(self, mode: Kf3Mode | str = Kf3Mode.ESP32) -> None:
        self.mode = Kf3Mode(mode)
        self.reference = REFERENCES[self.mode]
        ref = self.reference
        self.configure(ref.z_meas_variance, ref.accel_variance, ref.bias_variance, 0.0, 0.0, 0.0)

    def configure(
        self,
        zMeasVariance: float,
        zAccelVariance: float,
        zAccelBiasVariance: float,
        z0: float,
        v0: float = 0.0,
        bias0: float = 0.0,
        P0: tuple[float, float, float] | None = None,
    ) -> None:
        """Set the variances (cm^2, (cm/s^2)^2, (cm/s^2)^2 per step) and the initial state.

        The parameter names are the seed's (``kalmanFilter3_configure``) so the two read alike.

        ``P0`` is the initial covariance diagonal; None takes the mode's reference value.
        """
        self.z_meas_variance = float(zMeasVariance)
        self.accel_variance = float(zAccelVariance)
        self.bias_variance = float(zAccelBiasVariance)
        self.x = np.array([z0, v0, bias0], dtype=float)
        self.P = np.diag(np.asarray(P0 if P0 is not None else self.reference.p0_diag, float))

    @property
    def z(self) -> float:
        return float(self.x[0])

    @property
    def v(self) -> float:
        return float(self.x[1])

    @property
    def bias(self) -> float:
        return float(self.x[2])

    def predict(self, a_meas: float, dt: float) -> None:
        """Propagate by ``dt`` seconds with measured vertical acceleration ``a_meas`` (cm/s^2,
        up +, gravity removed, bias still in it)."""
        # The state, the update and the covariance all run on plain floats. The covariance
        # product F P F^T is written out in the order of the compiled batch kernel
        # (vario/fast.py: row times column, terms summed left to right), with F's zeros and
        # ones left out (0 * p and 1 * p add nothing to a finite sum): numpy's 3 x 3 `@`
        # entered OpenBLAS cold on every barometer sample, 17-53 us where its arithmetic is a
        # few dozen flops (docs/performance.md), and summed in its own order.
        ref = self.reference
        z, v, b = self.x.tolist()
        accel = a_meas - b
        if ref.semi_implicit:
            v = v + accel * dt
            z = z + v * dt
        else:
            z = z + v * dt
            v = v + accel * dt
        self.x = np.array([z, v, b])

        if ref.adaptive_accel_variance:
            lo, hi = AVARIO_ACCEL_VARIANCE_RANGE
            variance = abs(accel) / AVARIO_ACCEL_VARIANCE_DIVISOR
            self.accel_variance = float(min(max(variance, lo), hi))
        dt2 = dt * dt
        f01, f02, f12 = dt, -0.5 * dt2, -dt
        sa2 = self.accel_variance
        q00 = 0.25 * dt2 * dt2 * sa2
        q01 = 0.5 * dt2 * dt * sa2
        q11 = dt2 * sa2
        (p00, p01, p02), (p10, p11, p12), (p20, p21, p22) = self.P.tolist()
        # T = F P (F's rows: (1, dt, -dt^2/2), (0, 1, -dt), (0, 0, 1))
        t00, t01, t02 = p00 + f01 * p10 + f02 * p20, p01 + f01 * p11 + f02 * p21, \
            p02 + f01 * p12 + f02 * p22
        t10, t11, t12 = p10 + f12 * p20, p11 + f12 * p21, p12 + f12 * p22
        # F P F^T + Q: each row of T times F's rows
        self.P = np.array([
            [t00 + t01 * f01 + t02 * f02 + q00, t01 + t02 * f12 + q01, t02],
            [t10 + t11 * f01 + t12 * f02 + q01, t11 + t12 * f12 + q11, t12],
            [p20 + p21 * f01 + p22 * f02, p21 + p22 * f12, p22 + self.bias_variance],
        ])

    def update(self, z_meas: float) -> float:
        """Fuse one barometric altitude (cm); return the innovation (cm)."""
        (p00, p01, p02), (p10, p11, p12), (p20, p21, p22) = self.P.tolist()
        x0, x1, x2 = self.x.tolist()
        innovation = z_meas - x0
        s = p00 + self.z_meas_variance
        k0, k1, k2 = p00 / s, p10 / s, p20 / s
        self.x = np.array([x0 + k0 * innovation, x1 + k1 * innovation, x2 + k2 * innovation])
        # P = (I - K H) P; symmetrised so float rounding cannot make it drift apart.
        a00, a01, a02 = p00 - k0 * p00, p01 - k0 * p01, p02 - k0 * p02
        a10, a11, a12 = p10 - k1 * p00, p11 - k1 * p01, p12 - k1 * p02
        a20, a21, a22 = p20 - k2 * p00, p21 - k2 * p01, p22 - k2 * p02
        self.P = np.array([
            [0.5 * (a00 + a00), 0.5 * (a01 + a10), 0.5 * (a02 + a20)],
            [0.5 * (a10 + a01), 0.5 * (a11 + a11), 0.5 * (a12 + a21)],
            [0.5 * (a20 + a02), 0.5 * (a21 + a12), 0.5 * (a22 + a22)],
        ])
        return float(innovation)

    def step(self, z_meas: float, a_meas: float, dt: float) -> float:
        """One reference update call: predict with ``a_meas`` over ``dt``, then fuse ``z_meas``."""
        self.predict(a_meas, dt)
        return self.update(z_meas)

    def as_dict(self) -> dict[str, object]:
        return {
            "mode": self.mode.value,
            "x": [float(c) for c in self.x],
            "P": [[float(c) for c in row] for row in self.P],
            "variances": [self.z_meas_variance, self.accel_variance, self.bias_variance],
        }

    def load_dict(self, d: dict[str, object]) -> None:
        self.mode = Kf3Mode(d["mode"])
        self.reference = REFERENCES[self.mode]
        self.x = np.array(d["x"], dtype=float)
        self.P = np.array(d["P"], dtype=float)
        zv, av, bv = (float(c) for c in d["variances"])  # type: ignore[attr-defined]  # a saved state's variances: three numbers
        self.z_meas_variance, self.accel_variance, self.bias_variance = zv, av, bv
