"""The "madgwick" estimator: Madgwick's AHRS with the seed's accelerometer gate.

The seed (Nair 2016) runs the x-io reference code in NED and adds one tweak: the
accelerometer is used only while ``0.6 g < |a| < 1.4 g``; outside that window the step
integrates the gyro alone, and the whole gradient step (accelerometer and magnetometer) is
skipped. ``accel_gate_g`` sets the window (None: never gate). Whether the gate was open is in
each estimate's diagnostics (``gate_open``) and counted (``gate_closed_steps``).

Reference modes: ``mag_reference="xio_release"`` and ``inv_sqrt="fast32"`` reproduce the
x-io release to within float32 rounding (about 1e-6 per component; see ``core.py``). The
defaults are the paper's magnetometer reference and an exact 1/sqrt: the release's halved
field reference is a known defect that halves the heading correction and, on a tilted board,
moves the point the magnetometer pulls towards off the true attitude (on data set A at beta
0.1: 0.50 deg total RMS error for the release form, 0.29 deg for the paper form), and the fast
square root leaves the quaternion 0.17 % short of unit length.
With a 6-DOF setup (no magnetometer) the two magnetometer modes are identical.
By default (not in the presets) the board's rests are detected (``common/rest.py``): there
the soft gate is off and the gyro bias is learned (``rest_gyro_bias_rad_s``), subtracted
from every gyro sample the filter integrates.
"""

from __future__ import annotations

import math
from typing import Any, ClassVar, Literal

import numpy as np
from pydantic import Field

from imuhal.core.blocks import Block
from imuhal.core.frames import FloatArray
from imuhal_filters.common.ahrs import (
    NO_VECTOR,
    AhrsEstimator,
    AhrsSettings,
    ImuStep,
    kernel_readings,
    rest_columns,
)
from imuhal_filters.common.fast import Kernel, c_array
from imuhal_filters.common.gate import AccelGate, GateBounds, SoftGateSettings
from imuhal_filters.common.quat import Vec
from imuhal_filters.common.rest import RestSettings
from imuhal_filters.madgwick.core import MagReference, madgwick_step
from imuhal_filters.madgwick.fast import madgwick_block, madgwick_rows, madgwick_sample
from imuhal_filters.madgwick.inv_sqrt import INV_SQRT

SEED_GATE_G = (0.6, 1.4)

_NO_TIMES = np.zeros(0, dtype=np.int64)
_NO_ROWS = np.zeros((0, 3))
_NO_VECTOR = np.zeros(3)
"""A block step's magnetometer arguments when there is no magnetometer block."""


def _times(block: Block) -> np.ndarray:
    """A block's time stamps as the block step takes them (C-ordered int64: its unchecked
    call reads memory as declared; no copy when they already are)."""
    return np.ascontiguousarray(block.t_ns, dtype=np.int64)


class MadgwickSettings(AhrsSettings, SoftGateSettings, RestSettings):
    PRESETS: ClassVar[dict[str, dict[str, Any]]] = {
        # the x-io release as published: identity start, halved field reference, fast 1/sqrt
        "reference": {"initial_attitude": "identity", "turn_compensation": False,
                      "accel_soft_gate_g": None,
                      "accel_gate_g": None, "mag_reference": "xio_release",
                      "inv_sqrt": "fast32", "beta": 0.1, "rest_detection": False},
        # the seed's copy (Nair 2016 / the author's firmware): x-io with the 0.6-1.4 g gate
        "seed": {"initial_attitude": "identity", "turn_compensation": False,
                 "accel_soft_gate_g": None,
                 "accel_gate_g": SEED_GATE_G, "mag_reference": "xio_release", "beta": 0.6,
                 "rest_detection": False},
        # hand-held motion (BROAD): the soft gate and the low gain that keep a glider's tilt
        # in turns cost accuracy when the board is waved about (docs/estimators.md)
        "handheld": {"beta": 0.1, "accel_soft_gate_g": None},
    }

    beta: float = Field(0.03, ge=0.0)
    """Gradient step gain (rad/s). Default 0.03 with the 0.05 g soft gate: the flight choice,
    measured on the emulated ``thermal`` and ``rc-flight`` (docs/estimators.md). On hand-held
    motion it is not the best: BROAD 9-DOF total 9.2 deg against 4.9 for beta 0.1 without the
    soft gate (``preset: handheld``). x-io's default is 0.1 (``preset: reference``), the seed
    firmware's 0.6 (``preset: seed``)."""
    mag_reference: MagReference = MagReference.PAPER
    """``paper`` (default, corrected) or ``xio_release`` (the release's halved reference)."""
    inv_sqrt: Literal["exact", "fast32"] = "exact"
    """``fast32`` reproduces the release's 0x5f3759df normalisation (reference mode only)."""
    accel_gate_g: GateBounds | None = None
    """Use the accelerometer only while lower < |a| < upper (g); None (default) disables the
    gate: it hurts hand-held use (BROAD 4.75 deg without, 5.87 deg with the seed's 0.6-1.4 g)
    and turn compensation removes what it was meant to keep out (docs/estimators.md)."""
    use_mag: bool = True
    """Fuse magnetometer samples (9-DOF); False runs the 6-DOF update even when mag arrives."""


class MadgwickEstimator(AhrsEstimator):
    """Madgwick gradient-descent AHRS (6-DOF, or 9-DOF when magnetometer samples arrive)."""

    name: ClassVar[str] = "madgwick"
    # from the settings' defaults, so that `imuhal plugins` cannot quote stale ones
    description: ClassVar[str] = (
        "Madgwick gradient-descent AHRS (x-io release, corrected): beta "
        f"{MadgwickSettings().beta:g}, {MadgwickSettings().accel_soft_gate_g:g} g soft "
        "accel gate, turn compensated; presets reference, seed "
        f"({SEED_GATE_G[0]:g}-{SEED_GATE_G[1]:g} g gate), handheld"
    )
    Settings: ClassVar[type[MadgwickSettings]] = MadgwickSettings
    settings: MadgwickSettings

    def _reset_filter(self) -> None:
        self._gate = AccelGate.from_bounds(self.settings.accel_gate_g)
        self._gate_lower_g, self._gate_upper_g = self._gate.lower_g, self._gate.upper_g
        self._inv_sqrt = INV_SQRT[self.settings.inv_sqrt]
        self._counters["gate_closed_steps"] = 0
        # read at every step: kept as plain attributes
        self._use_mag = self.settings.use_mag
        self._soft_gate_g = self.settings.accel_soft_gate_g
        self._beta = self.settings.beta
        self._mag_reference = self.settings.mag_reference
        self._paper = self._mag_reference is MagReference.PAPER
        self._soft_width = 0.0 if self._soft_gate_g is None else float(self._soft_gate_g)
        # the compiled per-sample step where it pays (the AOT extension; fast.py), for the
        # exact 1/sqrt it implements; else _step in Python
        self._block_chosen = False  # the block step's backend: chosen again at its next use
        self._sample_kernel = (madgwick_sample.per_sample()
                               if self.settings.inv_sqrt == "exact" else None)

    def _compiled_step(self, gyro: Vec, accel_m_s2: Vec | None, mag: Vec | None, dt: float,
                       measured_m_s2: Vec | None) -> dict[str, Any]:
        """``_step`` in the compiled per-sample kernel: the same floats (tests compare them)."""
        gx, gy, gz = gyro
        f = NO_VECTOR if measured_m_s2 is None else measured_m_s2
        readings = kernel_readings(accel_m_s2, mag, self._use_mag)
        have_a, use_m = readings[0], readings[4]
        q0, q1, q2, q3, gate_open, weight, lx, ly, lz = self._sample_kernel(
            *self._q, gx, gy, gz, *readings, self._beta,
            self._gate_lower_g, self._gate_upper_g, self._soft_width, self._paper, dt,
            self._at_rest, *f)
        self._q = (q0, q1, q2, q3)
        self._linear_ned = (lx, ly, lz)
        if have_a and not gate_open:
            self._counters["gate_closed_steps"] += 1
        return {"dt_s": dt, "turn_compensation": self._kinematics.source,
                "gate_open": gate_open, "accel_used": gate_open,
                "mag_used": gate_open and use_m, "accel_weight": weight,
                "at_rest": self._at_rest, "rest_gyro_bias_rad_s": self.rest_gyro_bias_rad_s}

    def _step(self, step: ImuStep) -> dict[str, Any]:
        accel = step.accel_g
        # at rest the reading is gravity: no soft gate
        gate_open, weight = self._gate.gates(
            accel, None if self._at_rest else self._soft_gate_g, self._q)
        if accel is not None and not gate_open:
            self._counters["gate_closed_steps"] += 1
        mag = step.mag_ut if self._use_mag else None
        self._q = madgwick_step(
            self._q,
            step.gyro_rad_s,
            accel if gate_open else None,
            mag,
            self._beta * weight,
            step.dt_s,
            mag_reference=self._mag_reference,
            inv_sqrt=self._inv_sqrt,
        )
        return {
            "gate_open": gate_open,
            "accel_used": gate_open,
            "mag_used": gate_open and mag is not None,
            "accel_weight": weight,
            "at_rest": self._at_rest,
            "rest_gyro_bias_rad_s": self.rest_gyro_bias_rad_s,
        }

    _compiled_kernel: ClassVar[Kernel | None] = madgwick_rows
    _kernel_diag_width: ClassVar[int] = 7

    def _run_kernel(self, gyro: FloatArray, accel: FloatArray, mag: FloatArray,
                    dts: FloatArray, out: FloatArray, diag: FloatArray) -> bool:
        """The rows in the compiled kernel (``fast`` extra) when it covers this setup; see
        ``AhrsEstimator._run_kernel``."""
        s = self.settings
        if s.inv_sqrt != "exact":
            return False
        gate = self._gate
        rest, params = self._rest_arrays()
        q, turn_sum, closed = self._rows_kernel()(
            np.array(self._q), gyro, accel, mag, dts, float(s.beta), gate.lower_g,
            gate.upper_g, 0.0 if s.accel_soft_gate_g is None else float(s.accel_soft_gate_g),
            s.mag_reference is MagReference.PAPER, s.use_mag, s.turn_compensation,
            self._kinematics.turn_sum, out, diag, rest, params)
        self._kernel_finished(q, len(gyro), closed, turn_sum, rest)
        return True

    def _block_kernel(self) -> bool:
        return self.settings.inv_sqrt == "exact"

    _block_call: Any = None
    _block_chosen: bool = False

    def _has_block_step(self) -> bool:
        if not self._block_chosen:  # as ``_rows_kernel``: the backend looked up once
            self._block_call = madgwick_block.unchecked() if madgwick_block.available() \
                and self.settings.inv_sqrt == "exact" else None
            self._block_chosen = True
        return self._block_call is not None

    def _block_step(self, gyro: Block, accel: Block | None, mag: Block | None
                    ) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray] | None:
        """``AhrsEstimator._block_step`` in ``madgwick_block`` (the same floats as the frames
        one by one: tests/filters/test_ahrs_blocks.py)."""
        if accel is None or not self._has_block_step():
            return None
        s = self.settings
        m = len(gyro)
        out = np.empty((m, 4))
        diag = np.empty((m, 7))
        dts = np.empty(m)
        lin = np.empty((m, 3))
        rest, params = self._rest_arrays()
        speed = s.nominal_airspeed_m_s if s.turn_compensation else None
        last = self._last_gyro_t_ns
        mag_t, mag_v = (_NO_TIMES, _NO_ROWS) if mag is None else \
            (_times(mag), c_array(mag.values))
        held, held_t = self._mag_ut, self._mag_t_ns
        max_age = s.max_aux_age_s
        q, turn_sum, closed, fallbacks, stale, done = self._block_call(
            np.array(self._q), _times(gyro), c_array(gyro.values), _times(accel),
            c_array(accel.values), mag_t, mag_v, mag is not None, self.uses_mag,
            _NO_VECTOR if held is None else np.array(held), 0 if held_t is None else held_t,
            held is not None and held_t is not None,
            math.nan if max_age is None else float(max_age), 0 if last is None else last,
            last is not None, self._gyro_fs, self._accel_fs,
            float(s.sample_period_s), s.dt_from_timestamps, float(s.max_dt_s),
            math.nan if speed is None else float(speed), float(s.beta), self._gate.lower_g,
            self._gate.upper_g, self._soft_width, self._paper, s.use_mag,
            s.turn_compensation, self._kinematics.turn_sum, out, diag, dts, lin, rest, params)
        if not done:
            return None
        self._block_step_done(gyro, accel, mag, fallbacks)
        self._counters["stale_mag"] += stale
        self._kernel_finished(q, m, closed, turn_sum, rest)
        return out, diag, dts, lin

    def _kernel_row_diagnostics(self, dts: FloatArray, diag: FloatArray, source: str
                                ) -> list[dict[str, Any]]:
        return [{"dt_s": dt, "turn_compensation": source, "gate_open": g == 1.0,
                 "accel_used": g == 1.0, "mag_used": m == 1.0, "accel_weight": w,
                 "at_rest": r == 1.0, "rest_gyro_bias_rad_s": (bx, by, bz)}
                for dt, (g, m, w, r, bx, by, bz) in zip(dts.tolist(), diag.tolist(),
                                                        strict=True)]

    def _kernel_diagnostics(self, diag: FloatArray) -> dict[str, Any]:
        gate_open = diag[:, 0].astype(np.int64)
        return {"gate_open": gate_open, "accel_used": gate_open,
                "mag_used": diag[:, 1].astype(np.int64), "accel_weight": diag[:, 2],
                **rest_columns(diag)}

    def _filter_state(self) -> dict[str, Any]:
        return {}

    def _set_filter_state(self, state: dict[str, Any]) -> None:
        return None
