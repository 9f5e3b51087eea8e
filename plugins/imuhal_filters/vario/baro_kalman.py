"""Two-state barometer-only altitude / climb-rate Kalman filter (the seed's starting point).

State ``x = [z, v]``: altitude (m, up +) and climb rate (m/s, up +). Model: a particle on the
vertical axis with constant velocity, perturbed by white acceleration of standard deviation
``sigma_a`` (thermals, sink, turbulence, pilot input). Measurement: barometric altitude with
white noise of standard deviation ``sigma_z``.

    F = [[1, dt], [0, 1]]
    Q = sigma_a^2 [[dt^4/4, dt^3/2], [dt^3/2, dt^2]]
    H = [1, 0],  R = sigma_z^2

This is the "works well enough, but a bit laggy" filter of the seed (Nair 2016): with altitude
only, the climb rate must be inferred from successive noisy altitudes, so a smoother climb rate
costs response delay. The 3-state filter in ``kf3`` adds the accelerometer to break that trade.
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass
class BaroKalman2:
    """Constant-velocity Kalman filter in SI units (m, m/s). Covariance stored as 3 floats."""

    accel_var: float
    """sigma_a^2 in (m/s^2)^2: variance of the unmodelled vertical acceleration."""
    meas_var: float
    """sigma_z^2 in m^2: variance of the barometric altitude."""
    z: float = 0.0
    v: float = 0.0
    pzz: float = 1.0
    pzv: float = 0.0
    pvv: float = 1.0

    def initialise(self, z_m: float, v_m_s: float, pzz: float, pvv: float) -> None:
        self.z, self.v = z_m, v_m_s
        self.pzz, self.pzv, self.pvv = pzz, 0.0, pvv

    def predict(self, dt_s: float) -> None:
        """Propagate state and covariance by ``dt_s`` seconds (P = F P F^T + Q)."""
        dt = dt_s
        self.z += self.v * dt
        q = self.accel_var
        dt2 = dt * dt
        pzz = self.pzz + 2.0 * dt * self.pzv + dt2 * self.pvv + q * dt2 * dt2 / 4.0
        pzv = self.pzv + dt * self.pvv + q * dt2 * dt / 2.0
        pvv = self.pvv + q * dt2
        self.pzz, self.pzv, self.pvv = pzz, pzv, pvv

    def update(self, z_meas_m: float) -> float:
        """Fuse one altitude measurement (m); return the innovation (m)."""
        innovation = z_meas_m - self.z
        s = self.pzz + self.meas_var
        kz = self.pzz / s
        kv = self.pzv / s
        self.z += kz * innovation
        self.v += kv * innovation
        # P = (I - K H) P, written out for the symmetric 2x2 case.
        pzz, pzv, pvv = self.pzz, self.pzv, self.pvv
        self.pzz = pzz - kz * pzz
        self.pzv = pzv - kz * pzv
        self.pvv = pvv - kv * pzv
        return innovation

    def as_dict(self) -> dict[str, float]:
        return {"z": self.z, "v": self.v, "pzz": self.pzz, "pzv": self.pzv, "pvv": self.pvv}

    def load_dict(self, d: dict[str, float]) -> None:
        self.z, self.v = float(d["z"]), float(d["v"])
        self.pzz, self.pzv, self.pvv = float(d["pzz"]), float(d["pzv"]), float(d["pvv"])
