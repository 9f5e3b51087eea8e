"""The gyro bias of the "decoupled" estimator: a Kalman filter on a constant-ish bias.

After Laidig and Seel (VQF, Information Fusion 91, 2023), written here on plain floats. The
state is the gyro bias b (body axes, rad/s) with its covariance P; P is kept in (deg/s)^2 so
the settings read in the unit people quote for gyros. Between updates P grows so that a bias
known exactly would be uncertain by ``sigma_motion`` after ``forgetting_s`` (a bias drifts
with temperature); it never grows past the initial uncertainty. Two kinds of measurement:

- **at rest** the low-passed gyro is the bias itself: e = gyro_lp - b, H = I, variance from
  ``sigma_rest`` (small: a few seconds of rest pin the bias down);
- **in motion** the inclination correction of the last step is a measurement of the bias
  projected into the earth frame: a bias error d turns the strapdown by R d per second, and
  the accelerometer correction turns it back. Because the correction comes from a low-passed
  accelerometer, the model uses the same low-pass of R and of R b: y = LP(R b) - c / dt,
  H = LP(R) (x and y rows). The vertical row is a weak pseudo-measurement "no vertical bias"
  (``vertical_forgetting``) that keeps the unobservable earth-vertical part bounded.

Each variance W is chosen so that repeated updates settle P at sigma^2 (W = p^2 / V + p
for p = sigma^2 and V the growth per step), as VQF does; a disagreement e is clipped to the
bias clip so one bad step (the first correction, a knock) cannot throw the bias far.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

Mat3 = list[list[float]]
Vec = tuple[float, float, float]


@dataclass(frozen=True, slots=True)
class BiasParams:
    """Uncertainties in deg/s, times in seconds, the clip in rad/s."""

    sigma_init_deg_s: float = 0.5
    forgetting_s: float = 100.0
    sigma_motion_deg_s: float | None = 0.1
    """None: no updates in motion (bias from rest only)."""
    vertical_forgetting: float = 1e-4
    sigma_rest_deg_s: float = 0.03
    clip_rad_s: float = math.radians(2.0)


def _mul(a: Mat3, b: Mat3) -> Mat3:
    return [[a[i][0] * b[0][j] + a[i][1] * b[1][j] + a[i][2] * b[2][j] for j in range(3)]
            for i in range(3)]


def _mul_bt(a: Mat3, b: Mat3) -> Mat3:
    """a b^T."""
    return [[a[i][0] * b[j][0] + a[i][1] * b[j][1] + a[i][2] * b[j][2] for j in range(3)]
            for i in range(3)]


def inv3(m: Mat3) -> Mat3:
    """Inverse of a 3x3 matrix (adjugate over determinant)."""
    (a, b, c), (d, e, f), (g, h, i) = m
    A, B, C = e * i - f * h, f * g - d * i, d * h - e * g
    det = a * A + b * B + c * C
    r = 1.0 / det
    return [[A * r, (c * h - b * i) * r, (b * f - c * e) * r],
            [B * r, (a * i - c * g) * r, (c * d - a * f) * r],
            [C * r, (b * g - a * h) * r, (a * e - b * d) * r]]


IDENTITY3: Mat3 = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]


class GyroBiasKalman:
    """Bias estimate ``b`` (rad/s) and its covariance ``p`` ((deg/s)^2)."""

    def __init__(self, params: BiasParams, bias: Vec = (0.0, 0.0, 0.0)) -> None:
        self.params = params
        self.p0 = params.sigma_init_deg_s ** 2
        self.b: Vec = self._clip3(bias)
        self.p: Mat3 = [[self.p0, 0.0, 0.0], [0.0, self.p0, 0.0], [0.0, 0.0, self.p0]]

    def _clip3(self, v: Vec) -> Vec:
        c = self.params.clip_rad_s
        return (max(-c, min(c, v[0])), max(-c, min(c, v[1])), max(-c, min(c, v[2])))

    def growth(self, dt: float) -> float:
        """Variance added per step of ``dt`` s ((deg/s)^2)."""
        return 0.01 * dt / self.params.forgetting_s

    def _w(self, sigma_deg_s: float, dt: float) -> float:
        p = sigma_deg_s ** 2
        return p * p / max(self.growth(dt), 1e-30) + p

    def predict(self, dt: float) -> None:
        v = self.growth(dt)
        for i in range(3):
            if self.p[i][i] < self.p0:
                self.p[i][i] += v

    def rest_update(self, gyro_lp: Vec, dt: float) -> None:
        """At rest the low-passed gyro (rad/s) measures the bias directly."""
        b = self.b
        e = (gyro_lp[0] - b[0], gyro_lp[1] - b[1], gyro_lp[2] - b[2])
        w = self._w(self.params.sigma_rest_deg_s, dt)
        self._update(e, IDENTITY3, (w, w, w))

    def motion_update(self, e: Vec, h: Mat3, dt: float) -> None:
        """In motion: the disagreement ``e`` (rad/s, earth frame) with the measurement matrix
        ``h`` (the low-passed body -> earth rotation)."""
        sigma = self.params.sigma_motion_deg_s
        if sigma is None:
            return
        w = self._w(sigma, dt)
        self._update(e, h, (w, w, w / max(self.params.vertical_forgetting, 1e-10)))

    def _update(self, e: Vec, h: Mat3, w: Vec) -> None:
        e = self._clip3(e)
        p = self.p
        ph_t = _mul_bt(p, h)                 # P H^T
        s = _mul(h, ph_t)                    # H P H^T
        for i in range(3):
            s[i][i] += w[i]
        k = _mul(ph_t, inv3(s))              # P H^T S^-1
        b = self.b
        self.b = self._clip3((b[0] + k[0][0] * e[0] + k[0][1] * e[1] + k[0][2] * e[2],
                              b[1] + k[1][0] * e[0] + k[1][1] * e[1] + k[1][2] * e[2],
                              b[2] + k[2][0] * e[0] + k[2][1] * e[1] + k[2][2] * e[2]))
        khp = _mul(_mul(k, h), p)
        self.p = [[p[i][j] - khp[i][j] for j in range(3)] for i in range(3)]

    def information(self) -> Mat3:
        """P^-1 ((deg/s)^-2): how much the estimate is worth, to fuse two passes."""
        return inv3(self.p)


def fuse(b1: Vec, info1: Mat3, b2: Vec, info2: Mat3) -> tuple[Vec, Mat3]:
    """Two independent estimates of one bias weighted by their information: (b, P^-1)."""
    info = [[info1[i][j] + info2[i][j] for j in range(3)] for i in range(3)]
    rhs = [sum(info1[i][j] * b1[j] + info2[i][j] * b2[j] for j in range(3)) for i in range(3)]
    cov = inv3(info)
    b = tuple(sum(cov[i][j] * rhs[j] for j in range(3)) for i in range(3))
    return (b[0], b[1], b[2]), info

