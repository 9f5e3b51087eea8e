"""Run a Freescale Kalman filter over whole arrays of fast samples (the tests' entry point).

Inputs are in the reference's units and in the sensor axes and accelerometer sign of the
chosen coordinate system (for NED: body forward-right-down, accelerometer gravity positive,
g; gyro deg/s; magnetometer calibrated uT). Row ``i`` is fast sample ``i``; a Kalman step
runs after every ``oversample_ratio`` rows, on the gyro rows of that window and on the last
accelerometer/magnetometer row of it (or the window mean, per ``accel_mag_input``). With rest
detection on (the default; ``rest.WindowRest``) every row is a tick of the detector, in the
Python steps and in the compiled kernel alike.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from imuhal.core.conventions import NED, convert_quat
from imuhal.core.frames import FloatArray
from imuhal_filters.common.rest import RestSettings, rest_params
from imuhal_filters.freescale.coords import CONVENTION, CoordinateSystem
from imuhal_filters.freescale.fast import KERNEL_SETTINGS, freescale_rows
from imuhal_filters.freescale.kalman import FIELD_LENGTH_RATE_UT_S, FreescaleKalman, KalmanStep
from imuhal_filters.freescale.rest import WindowRest
from imuhal_filters.freescale.settings import (
    Freescale6DofSettings,
    Freescale9DofSettings,
    FreescaleCommonSettings,
)


@dataclass(frozen=True)
class BatchResult:
    """One row per Kalman step. Quaternions are scalar first."""

    row: np.ndarray
    """Index of the fast sample that completed each Kalman window."""
    valid: np.ndarray
    """False for the initialising step."""
    q_sensor_to_global: FloatArray
    """(n, 4) the filter's own quaternion (for NED: body -> NED)."""
    q_body_to_ned: FloatArray
    """(n, 4) body -> NED whatever the coordinate system."""
    euler_deg: FloatArray
    """(n, 3) the system's own roll phi, pitch theta, yaw psi (0..360)."""
    gyro_offset_dps: FloatArray
    """(n, 3) gyro offset estimate (deg/s, sensor axes)."""
    inclination_deg: FloatArray
    mag_jamming: np.ndarray


def run_9dof(accel_g: FloatArray, gyro_dps: FloatArray, mag_ut: FloatArray,
             settings: Freescale9DofSettings | None = None) -> BatchResult:
    """fRun_9DOF_GBY_KALMAN over arrays of shape (n, 3)."""
    return _run(settings or Freescale9DofSettings(), accel_g, gyro_dps, mag_ut, use_mag=True)


def run_6dof(accel_g: FloatArray, gyro_dps: FloatArray,
             settings: Freescale6DofSettings | None = None) -> BatchResult:
    """fRun_6DOF_GY_KALMAN over arrays of shape (n, 3)."""
    return _run(settings or Freescale6DofSettings(), accel_g, gyro_dps, None, use_mag=False)


def _run(settings: FreescaleCommonSettings, accel_g: FloatArray, gyro_dps: FloatArray,
         mag_ut: FloatArray | None, *, use_mag: bool) -> BatchResult:
    accel = np.asarray(accel_g, dtype=float)
    gyro = np.asarray(gyro_dps, dtype=float)
    mag = None if mag_ut is None else np.asarray(mag_ut, dtype=float)
    if accel.shape != gyro.shape or (mag is not None and mag.shape != accel.shape):
        raise ValueError("accel, gyro and mag arrays must have the same (n, 3) shape")
    kf = FreescaleKalman(settings, use_mag=use_mag)
    ratio = settings.oversample_ratio
    average = settings.accel_mag_input == "average"
    ends = list(range(ratio - 1, len(accel), ratio))
    compiled = (freescale_rows.available()
                and set(type(settings).model_fields) <= KERNEL_SETTINGS | _REST_SETTINGS)
    rest = WindowRest(settings)
    rows, steps = _python_steps(kf, rest, accel, gyro, mag, ends, average, compiled)
    cs = settings.coordinate_system
    q, euler, offset, incl, jam, valid = _columns(steps)
    if len(rows) < len(ends):
        k_q, k_off, k_incl, k_jam, k_euler = _compiled_steps(kf, rest, accel, gyro, mag,
                                                             len(rows), ratio, average)
        rows += ends[len(rows):]
        q, euler = np.concatenate([q, k_q]), np.concatenate([euler, k_euler])
        offset, incl = np.concatenate([offset, k_off]), np.concatenate([incl, k_incl])
        jam = np.concatenate([jam, k_jam])
        valid = np.concatenate([valid, np.ones(len(k_q), dtype=bool)])
    return BatchResult(
        row=np.array(rows, dtype=int), valid=valid, q_sensor_to_global=q,
        q_body_to_ned=quats_body_to_ned(cs, q),
        euler_deg=euler, gyro_offset_dps=offset, inclination_deg=incl, mag_jamming=jam,
    )


def _python_steps(kf: FreescaleKalman, rest: WindowRest, accel: FloatArray,
                  gyro: FloatArray, mag: FloatArray | None, ends: list[int], average: bool,
                  compiled: bool) -> tuple[list[int], list[KalmanStep]]:
    """The Kalman steps in Python (the rest detector ``rest`` ticked on every row), one per
    window ending at each of ``ends``, until the filter is initialised and locked when the
    rest can run ``compiled``; the windows' last rows and the steps."""
    ratio = kf.s.oversample_ratio
    gyro_rad_s = np.radians(gyro)
    rows, steps = [], []
    for end in ends:
        if compiled and kf.initialised and kf.locked:
            break  # the rest in the compiled kernel
        window = slice(end - ratio + 1, end + 1)
        if rest.on:
            for i in range(window.start, window.stop):
                rest.tick(_vec(gyro_rad_s[i]), _vec(accel[i]), kf.s.fast_dt_s)
        a = accel[window].mean(axis=0) if average else accel[end]
        m = None
        if mag is not None:
            m = mag[window].mean(axis=0) if average else mag[end]
        steps.append(kf.step(a, gyro[window], m, at_rest=rest.take_window()))
        rows.append(end)
    return rows, steps


def _vec(row: FloatArray) -> tuple[float, float, float]:
    return (float(row[0]), float(row[1]), float(row[2]))


def _columns(steps: list[KalmanStep]) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray,
                                               np.ndarray, np.ndarray]:
    """The steps' quaternions, Euler angles, gyro offsets, inclinations, jamming and
    validity flags as columns (one row per step)."""
    q = np.array([st.q_sensor_to_global for st in steps]).reshape(-1, 4)
    euler = np.array([[st.euler_deg[k] for k in ("phi", "theta", "psi")]
                      for st in steps]).reshape(-1, 3)
    offset = np.array([st.gyro_offset_dps for st in steps]).reshape(-1, 3)
    incl = np.array([st.inclination_deg for st in steps])
    jam = np.array([st.mag_jamming for st in steps], dtype=bool)
    valid = np.array([st.valid for st in steps], dtype=bool)
    return q, euler, offset, incl, jam, valid


def _compiled_steps(kf: FreescaleKalman, rest: WindowRest, accel: FloatArray,
                    gyro: FloatArray, mag: FloatArray | None, done: int, ratio: int,
                    average: bool
                    ) -> tuple[FloatArray, FloatArray, FloatArray, np.ndarray, FloatArray]:
    """The Kalman steps of windows ``done``... in the compiled kernel (the filter is
    initialised and locked), the rest detector ``rest`` ticked there too; ``kf`` and
    ``rest`` are left as the Python steps would leave them."""
    s = kf.s
    n_win = len(accel) // ratio - done
    span = slice(done * ratio, (done + n_win) * ratio)
    g = np.ascontiguousarray(gyro[span].reshape(n_win, ratio, 3))
    g_rad = np.ascontiguousarray(np.radians(gyro[span]).reshape(n_win, ratio, 3))
    a_fast = np.ascontiguousarray(accel[span].reshape(n_win, ratio, 3))
    rest_state = np.array(rest.state, dtype=float)
    out_rest = np.zeros(n_win, dtype=bool)

    def measured(values: FloatArray) -> FloatArray:
        w = values[span].reshape(n_win, ratio, 3)
        return np.ascontiguousarray(w.mean(axis=1) if average else w[:, -1])

    a = measured(accel)
    m = measured(mag) if mag is not None else np.zeros((n_win, 3))
    noise = kf._measurement_noise()
    nine = kf.use_mag
    s9 = kf._s9() if nine else None
    out_q, out_b = np.empty((n_win, 4)), np.empty((n_win, 3))
    out_incl, out_jam = np.empty(n_win), np.zeros(n_win, dtype=bool)
    out_euler = np.empty((n_win, 3))
    incl = np.array([kf.inclination_deg])
    gate_closed = np.array([kf.gate_closed_s])
    gate = s.accel_innovation_gate_sigma
    mag_limit = s9.mag_max_accel_distrust if s9 else None
    mag_gate = s9.mag_innovation_gate_sigma if s9 else None
    reacquire = s9.mag_gate_reacquire_s if s9 else None
    kf.mag_gate = np.ascontiguousarray(kf.mag_gate, dtype=float)
    kf.qw = np.ascontiguousarray(kf.qw)
    freescale_rows(
        kf.q, kf.b, kf.a_sensor, kf.m_global, kf.qw, incl, a, g, m, nine,
        s.coordinate_system is CoordinateSystem.NED, s.coordinate_system.gravity_positive,
        s.fast_dt_s, s.kalman_dt_s, s.accel_decay,
        0.0 if s.accel_soft_gate_g is None else float(s.accel_soft_gate_g), noise,
        bool(s9 and s9.full_innovation_inverse), s9.field_strength_ut if s9 else 0.0,
        s.qw_gyro_offset_dps2, s.qv_gyro_dps2, s.qw_accel_g2,
        s9.disturbance_decay if s9 else 0.0, s9.qw_mag_disturbance_ut2 if s9 else 0.0,
        s9.max_inclination_deg if s9 else 90.0, _STYLE[s.coordinate_system],
        0.0 if gate is None else float(gate), s.accel_gate_reacquire_s, gate_closed,
        0.0 if mag_limit is None else float(mag_limit),
        0.0 if mag_gate is None else float(mag_gate), kf.mag_gate,
        math.inf if reacquire is None else float(reacquire),
        FIELD_LENGTH_RATE_UT_S * s.kalman_dt_s, rest_state,
        np.array(rest_params(s), dtype=float), g_rad, a_fast, out_q, out_b, out_incl, out_jam,
        out_euler, out_rest)
    rest.state = tuple(float(v) for v in rest_state)
    kf.inclination_deg = float(incl[0])
    kf.gate_closed_s = float(gate_closed[0])
    return out_q, out_b, out_incl, out_jam, out_euler


_REST_SETTINGS = frozenset(RestSettings.model_fields)
"""Rest detection's settings: the kernel ticks the same detector (``rest_params``)."""


_STYLE = {CoordinateSystem.NED: 0, CoordinateSystem.ANDROID: 1, CoordinateSystem.WIN8: 2}
"""The kernel's code for each system's Euler style."""


def quats_body_to_ned(cs: CoordinateSystem, q: FloatArray) -> FloatArray:
    """:func:`coords.quat_body_to_ned` of every row of ``q`` (n, 4) at once."""
    if not len(q):
        return np.zeros((0, 4))
    out = np.asarray(convert_quat(q, CONVENTION[cs], NED), dtype=float).reshape(-1, 4)
    n = np.sqrt(np.einsum("ij,ij->i", out, out))
    good = n > 1e-3
    out = np.where(good[:, None], out / np.where(good, n, 1.0)[:, None],
                   np.array([1.0, 0.0, 0.0, 0.0]))
    return np.where((out[:, 0] < 0.0)[:, None], -out, out)
