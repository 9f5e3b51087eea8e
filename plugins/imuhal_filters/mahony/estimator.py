"""The "mahony" estimator: the Mahony AHRS of the seed author's ESP32 vario firmware.

har-in-air/ESP32_IMU_BARO_GPS_VARIO fuses its MPU9250 with this filter at 500 Hz, proportional
gain 5 and no integral term, and feeds the accelerometer back only while
``0.75 g < |a| < 1.25 g`` (it compares ``|a|^2`` in mG^2 with 562500 and 1562500). Outside
that window the step integrates the gyro alone, magnetometer included. Those are the defaults
here; ``kp``, ``ki`` and ``accel_gate_g`` are settings. A non-zero ``ki`` makes the integral
term estimate the gyro bias (rad/s, in ``diagnostics`` as ``gyro_bias_rad_s``: the negated
integral feedback). By default (not in the presets) the board's rests are detected
(``common/rest.py``): there the soft gate is off and the gyro bias is learned
(``rest_gyro_bias_rad_s``), subtracted before the filter, integral term included, sees the
rate.
"""

from __future__ import annotations

from typing import Any, ClassVar

import numpy as np
from pydantic import Field

from imuhal.core.frames import FloatArray
from imuhal_filters.common.ahrs import (
    NO_VECTOR,
    AhrsEstimator,
    AhrsSettings,
    ImuStep,
    kernel_readings,
    rest_columns,
)
from imuhal_filters.common.fast import Kernel
from imuhal_filters.common.gate import AccelGate, GateBounds, SoftGateSettings
from imuhal_filters.common.quat import Vec
from imuhal_filters.common.rest import RestSettings
from imuhal_filters.mahony.core import mahony_step
from imuhal_filters.mahony.fast import mahony_rows, mahony_sample

_FIRMWARE: dict[str, Any] = {"initial_attitude": "identity", "turn_compensation": False,
                             "accel_soft_gate_g": None, "rest_detection": False,
                             "kp": 5.0, "ki": 0.0, "accel_gate_g": (0.75, 1.25)}


class MahonySettings(AhrsSettings, SoftGateSettings, RestSettings):
    PRESETS: ClassVar[dict[str, dict[str, Any]]] = {
        # the seed author's ESP32 firmware is both the reference and the seed here
        "reference": _FIRMWARE,
        "seed": _FIRMWARE,
    }

    kp: float = Field(0.5, ge=0.0)
    """Proportional gain (1/s). Default 0.5 (x-io's default): the firmware's 5 doubles the
    error on hand-held motion (BROAD 18.2 deg against 8.3 for a peer at 0.8) and lets turns
    and the launch tilt it (docs/estimators.md)."""
    ki: float = Field(0.0, ge=0.0)
    """Integral gain (1/s^2); 0 in the firmware (integral held at zero)."""
    accel_gate_g: GateBounds | None = None
    """Feedback only while lower < |a| < upper (g); None (default: the soft gate does the
    job without cutting off) disables it; the firmware's is 0.75-1.25 g (``preset: seed``)."""
    use_mag: bool = True
    """Fuse magnetometer samples (9-DOF); False runs the 6-DOF update."""


class MahonyEstimator(AhrsEstimator):
    """Mahony complementary AHRS with proportional-integral feedback and an accel gate."""

    name: ClassVar[str] = "mahony"
    # from the settings' defaults, so that `imuhal plugins` cannot quote stale ones
    description: ClassVar[str] = (
        f"Mahony complementary AHRS: Kp {MahonySettings().kp:g}, Ki {MahonySettings().ki:g}, "
        f"{MahonySettings().accel_soft_gate_g:g} g soft accel gate, turn compensated; "
        f"preset seed: the vario firmware's Kp {_FIRMWARE['kp']:g}, "
        f"{_FIRMWARE['accel_gate_g'][0]:g}-{_FIRMWARE['accel_gate_g'][1]:g} g gate"
    )
    Settings: ClassVar[type[MahonySettings]] = MahonySettings
    settings: MahonySettings

    def _reset_filter(self) -> None:
        self._gate = AccelGate.from_bounds(self.settings.accel_gate_g)
        self._gate_lower_g, self._gate_upper_g = self._gate.lower_g, self._gate.upper_g
        self._integral: Vec = (0.0, 0.0, 0.0)
        self._counters["gate_closed_steps"] = 0
        s = self.settings
        self._use_mag = s.use_mag
        self._kp, self._ki = float(s.kp), float(s.ki)
        self._soft_width = 0.0 if s.accel_soft_gate_g is None else float(s.accel_soft_gate_g)
        # the compiled per-sample step where it pays (the AOT extension; common/fast.py)
        self._sample_kernel = mahony_sample.per_sample()

    def _compiled_step(self, gyro: Vec, accel_m_s2: Vec | None, mag: Vec | None, dt: float,
                       measured_m_s2: Vec | None) -> dict[str, Any]:
        """``_step`` in the compiled per-sample kernel: the same floats (tests compare them)."""
        gx, gy, gz = gyro
        f = NO_VECTOR if measured_m_s2 is None else measured_m_s2
        readings = kernel_readings(accel_m_s2, mag, self._use_mag)
        have_a, use_m = readings[0], readings[4]
        q0, q1, q2, q3, ix, iy, iz, gate_open, weight, lx, ly, lz = self._sample_kernel(
            *self._q, *self._integral, gx, gy, gz, *readings,
            self._kp, self._ki, self._gate_lower_g, self._gate_upper_g, self._soft_width, dt,
            self._at_rest, *f)
        self._q = (q0, q1, q2, q3)
        self._linear_ned = (lx, ly, lz)
        self._integral = (ix, iy, iz)
        if have_a and not gate_open:
            self._counters["gate_closed_steps"] += 1
        return {"dt_s": dt, "turn_compensation": self._kinematics.source,
                "gate_open": gate_open, "accel_used": gate_open,
                "mag_used": gate_open and use_m, "gyro_bias_rad_s": (-ix, -iy, -iz),
                "accel_weight": weight, "at_rest": self._at_rest,
                "rest_gyro_bias_rad_s": self.rest_gyro_bias_rad_s}

    def _step(self, step: ImuStep) -> dict[str, Any]:
        accel = step.accel_g
        # at rest the reading is gravity: no soft gate
        gate_open, weight = self._gate.gates(
            accel, None if self._at_rest else self.settings.accel_soft_gate_g, self._q)
        if accel is not None and not gate_open:
            self._counters["gate_closed_steps"] += 1
        mag = step.mag_ut if self.settings.use_mag else None
        self._q, self._integral = mahony_step(
            self._q, self._integral, step.gyro_rad_s, accel if gate_open else None, mag,
            self.settings.kp * weight, self.settings.ki * weight, step.dt_s,
        )
        return {
            "gate_open": gate_open,
            "accel_used": gate_open,
            "mag_used": gate_open and mag is not None,
            "gyro_bias_rad_s": self.gyro_bias_rad_s,
            "accel_weight": weight,
            "at_rest": self._at_rest,
            "rest_gyro_bias_rad_s": self.rest_gyro_bias_rad_s,
        }

    _compiled_kernel: ClassVar[Kernel | None] = mahony_rows
    _kernel_diag_width: ClassVar[int] = 10

    def _run_kernel(self, gyro: FloatArray, accel: FloatArray, mag: FloatArray,
                    dts: FloatArray, out: FloatArray, diag: FloatArray) -> bool:
        """The rows in the compiled kernel (``fast`` extra); see ``AhrsEstimator._run_kernel``."""
        s = self.settings
        gate = self._gate
        rest, params = self._rest_arrays()
        q, integral, turn_sum, closed = self._rows_kernel()(
            np.array(self._q), np.array(self._integral), gyro, accel, mag, dts, float(s.kp),
            float(s.ki), gate.lower_g, gate.upper_g,
            0.0 if s.accel_soft_gate_g is None else float(s.accel_soft_gate_g), s.use_mag,
            s.turn_compensation, self._kinematics.turn_sum, out, diag, rest, params)
        self._integral = (float(integral[0]), float(integral[1]), float(integral[2]))
        self._kernel_finished(q, len(gyro), closed, turn_sum, rest)
        return True

    def _block_kernel(self) -> bool:
        return True

    def _kernel_row_diagnostics(self, dts: FloatArray, diag: FloatArray, source: str
                                ) -> list[dict[str, Any]]:
        return [{"dt_s": dt, "turn_compensation": source, "gate_open": g == 1.0,
                 "accel_used": g == 1.0, "mag_used": m == 1.0, "gyro_bias_rad_s": (bx, by, bz),
                 "accel_weight": w, "at_rest": r == 1.0, "rest_gyro_bias_rad_s": (rx, ry, rz)}
                for dt, (g, m, w, r, rx, ry, rz, bx, by, bz) in zip(dts.tolist(), diag.tolist(),
                                                                    strict=True)]

    def _kernel_diagnostics(self, diag: FloatArray) -> dict[str, Any]:
        gate_open = diag[:, 0].astype(np.int64)
        return {"gate_open": gate_open, "accel_used": gate_open,
                "mag_used": diag[:, 1].astype(np.int64), "gyro_bias_rad_s_0": diag[:, 7],
                "gyro_bias_rad_s_1": diag[:, 8], "gyro_bias_rad_s_2": diag[:, 9],
                "accel_weight": diag[:, 2], **rest_columns(diag)}

    @property
    def gyro_bias_rad_s(self) -> Vec:
        """The integral term's bias estimate (rad/s): what it adds to the gyro, negated."""
        ix, iy, iz = self._integral
        return (-ix, -iy, -iz)

    def _filter_state(self) -> dict[str, Any]:
        return {"integral": list(self._integral)}

    def _set_filter_state(self, state: dict[str, Any]) -> None:
        ix, iy, iz = (float(v) for v in state["integral"])
        self._integral = (ix, iy, iz)
