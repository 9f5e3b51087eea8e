"""Helper kernels every AHRS kernel shares (see common/fast.py): the accelerometer gate and
the row loop.

The gate is written once, here: the compiled steps (madgwick, mahony, freescale) call it as
helper kernels and the Python path (``common/gate.py``, ``freescale/kalman.py``) calls the
same functions as plain Python, so the two cannot drift apart. (:func:`accel_gate` names
:func:`unmodelled_accel_g` by its plain function: Python calls it directly, and the compiled
copy is bound to its kernel, ``common.fast.compiled_copy``.)

The row loop is made once per filter from the filter's step (:func:`ahrs_rows`, a helper
kernel calling the step's helper kernel). A step has this form::

    step(state, params, gx, gy, gz, have_a, ax, ay, az, use_m, mx, my, mz, dt, at_rest)
        -> (state, gate_open, weight, bias)

``state`` is a tuple of floats whose first four are the quaternion (body -> NED, scalar
first), ``params`` a tuple of the filter's settings, ``g`` the gyro (rad/s, body), ``a`` the
gravity-positive accelerometer reading (g; ``have_a`` False: none), ``m`` the magnetometer
(``use_m`` False: none or not used), ``dt`` the step (s); ``weight`` is the soft gate's and
``bias`` the filter's gyro bias estimate (rad/s; zeros for a filter without one). The row
loop runs the rest detector (:func:`rest_update`, ``common/rest.py``) before each step: the
step gets the gyro less the bias learned at rest, and ``at_rest`` (the board still: the
accelerometer reads gravity, so the soft gate's weight is 1).

Every kernel that calls these lists this module in its AOT fingerprint
(``Kernel.modules``), so an edit here makes the built extension's copies stale.
"""

from __future__ import annotations

import math
from typing import Any

from imuhal.core.frames import FloatArray
from imuhal_filters.common.fast import Kernel, jit

State = tuple[float, ...]

TO_G = -1.0 / 9.80665
"""Specific force (m/s^2) -> gravity-positive reading (g): ``gravity_positive_g``'s factor
(-1 / STANDARD_GRAVITY_M_S2)."""

NO_BIAS = (0.0, 0.0, 0.0)
"""The ``bias`` of a step whose filter estimates no gyro bias."""


def soft_gate_distrust(norm_g: float, width_g: float) -> float:
    """How much less an AHRS trusts an accelerometer reading of magnitude ``norm_g`` (g):
    1 + ((norm - 1) / width)^2 for a soft gate of ``width_g`` (g), 1 for ``width_g`` <= 0
    (no soft gate). The complementary filters weight their correction by its inverse, the
    Freescale Kalman filter multiplies its accelerometer noise by its square."""
    if width_g > 0.0:
        d = (norm_g - 1.0) / width_g
        return 1.0 + d * d
    return 1.0


soft_gate_distrust_kernel = jit(soft_gate_distrust)
""":func:`soft_gate_distrust` as a helper kernel."""


def unmodelled_accel_g(ax: float, ay: float, az: float, q0: float, q1: float, q2: float,
                       q3: float) -> float:
    """The size (g) of the acceleration nothing models in the gravity-positive reading ``a``
    (g, body; turn-compensated): ``|a - R(q)^T (0, 0, 1)|``, the reading minus the gravity
    the attitude ``q`` (body -> NED) predicts, i.e. the accelerometer's innovation. A
    horizontal acceleration ``h`` (g) turns the reading by ``atan(h)`` but changes its
    magnitude only by about ``h^2 / 2``: the vector sees it at first order, the magnitude
    (:func:`soft_gate_distrust`) at second."""
    ex = ax - 2.0 * (q1 * q3 - q0 * q2)
    ey = ay - 2.0 * (q2 * q3 + q0 * q1)
    ez = az - (q0 * q0 - q1 * q1 - q2 * q2 + q3 * q3)
    return math.sqrt(ex * ex + ey * ey + ez * ez)


unmodelled_accel_g_kernel = jit(unmodelled_accel_g)
""":func:`unmodelled_accel_g` as a helper kernel."""


def accel_gate(have_a: bool, ax: float, ay: float, az: float, q0: float, q1: float,
               q2: float, q3: float, lower_g: float, upper_g: float, width_g: float
               ) -> tuple[bool, float]:
    """The hard and soft accelerometer gates of a complementary filter at attitude ``q``
    (body -> NED), for the gravity-positive reading ``a`` (g; ``have_a`` False: none this
    step): whether the hard gate is open (``lower_g < |a| < upper_g``, strictly, as in the
    seeds; closed without a reading) and the weight of the correction,
    ``1 / (1 + (u / width_g)^2)`` with ``u`` the unmodelled acceleration
    (:func:`unmodelled_accel_g`; 1 without a reading or without a soft gate, ``width_g``
    <= 0)."""
    if not have_a:
        return False, 1.0
    n = math.sqrt(ax ** 2 + ay ** 2 + az ** 2)
    if width_g > 0.0:
        d = unmodelled_accel_g(ax, ay, az, q0, q1, q2, q3) / width_g
        return lower_g < n < upper_g, 1.0 / (1.0 + d * d)
    return lower_g < n < upper_g, 1.0


accel_gate_kernel = jit(accel_gate)
""":func:`accel_gate` as a helper kernel."""


def rest_update(r: State, p: State, gx: float, gy: float, gz: float, have_a: bool,
                ax: float, ay: float, az: float, dt: float) -> tuple[State, bool]:
    """One step of the rest detector (``common/rest.py``) for the gyro ``g`` (rad/s, body, as
    measured) and the gravity-positive reading ``a`` (g; ``have_a`` False: none), over
    ``dt`` (s). ``r`` is the state (started, low-passed gyro, low-passed accelerometer,
    still time, time at rest, learned bias), ``p`` the parameters (``rest.rest_params``).
    Returns the new state and whether the board is at rest this step. The bias is set from
    the low-passed rate at the first rest and averaged with time constant ``p[7]`` at
    every later rest step."""
    started, glx, gly, glz, alx, aly, alz, still_s, rest_s, bx, by, bz = r
    on, tau, dev_g2, dev_a2, min_s, first_max, max_rate, tau_b = p
    if on == 0.0:
        return r, False
    if not have_a:
        return (started, glx, gly, glz, alx, aly, alz, 0.0, rest_s, bx, by, bz), False
    if started == 0.0:
        started, glx, gly, glz, alx, aly, alz = 1.0, gx, gy, gz, ax, ay, az
    else:
        k = dt / (tau + dt)
        glx, gly, glz = glx + (gx - glx) * k, gly + (gy - gly) * k, glz + (gz - glz) * k
        alx, aly, alz = alx + (ax - alx) * k, aly + (ay - aly) * k, alz + (az - alz) * k
    dx, dy, dz = gx - glx, gy - gly, gz - glz
    ex, ey, ez = ax - alx, ay - aly, az - alz
    limit = first_max if rest_s == 0.0 else max_rate
    still = (dx * dx + dy * dy + dz * dz <= dev_g2 and ex * ex + ey * ey + ez * ez <= dev_a2
             and abs(glx - bx) <= limit and abs(gly - by) <= limit and abs(glz - bz) <= limit)
    still_s = still_s + dt if still else 0.0
    if still_s < min_s:
        return (started, glx, gly, glz, alx, aly, alz, still_s, rest_s, bx, by, bz), False
    if rest_s == 0.0:
        bx, by, bz = glx, gly, glz
    else:
        kb = dt / (tau_b + dt)
        bx, by, bz = bx + (gx - bx) * kb, by + (gy - by) * kb, bz + (gz - bz) * kb
    return (started, glx, gly, glz, alx, aly, alz, still_s, rest_s + dt, bx, by, bz), True


rest_update_kernel = jit(rest_update)
""":func:`rest_update` as a helper kernel."""


def ahrs_rows(step: Kernel) -> Kernel:
    """The row loop with ``step`` (a helper kernel of the form above), as a helper kernel:
    one per filter, compiled into its ``*_rows`` kernel. ``step`` is a closure variable,
    not an argument: numba then calls it directly, and a kernel that passed a compiled
    function as an argument could not be cached (its address is a dynamic global)."""

    def _ahrs_rows(state: State, params: tuple[Any, ...], gyro: FloatArray,
                   accel: FloatArray, mag: FloatArray, dts: FloatArray, use_mag: bool,
                   turn_on: bool, turn_sum: float, out: FloatArray, diag: FloatArray,
                   rest: FloatArray, rest_params: FloatArray) -> tuple[State, float, int]:
        """One ``step`` per row (rows resolved by ``common/rows.py``: a NaN accel or mag
        row means none this step; accel in m/s^2 specific force, body NED). ``out`` gets
        the quaternion after each row, ``diag`` its gate_open, mag_used, accel_weight,
        at_rest and the gyro bias learned at rest (rad/s, columns 4-6), and in columns 7-9
        (when it has them) the filter's own gyro bias (rad/s); a ``diag`` of one row is
        scratch (no diagnostics asked). ``rest`` is the rest detector's state (updated in
        place), ``rest_params`` its parameters (``common/rest.py``). With ``turn_on``, the
        gyro rate's magnitude (as measured) is added to ``turn_sum`` (the nominal-free
        turn bookkeeping). Returns the final state, the turn-rate sum and the number of
        steps with the gate closed."""
        closed = 0
        keep = diag.shape[0] == gyro.shape[0]
        with_bias = diag.shape[1] > 7
        r = (rest[0], rest[1], rest[2], rest[3], rest[4], rest[5], rest[6], rest[7], rest[8],
             rest[9], rest[10], rest[11])
        p = (rest_params[0], rest_params[1], rest_params[2], rest_params[3], rest_params[4],
             rest_params[5], rest_params[6], rest_params[7])
        for i in range(gyro.shape[0]):
            di = i if keep else 0
            gx, gy, gz = gyro[i, 0], gyro[i, 1], gyro[i, 2]
            have_a = not math.isnan(accel[i, 0])
            use_m = not math.isnan(mag[i, 0]) and use_mag
            if turn_on:
                turn_sum += math.sqrt(gx ** 2 + gy ** 2 + gz ** 2)
            ax = ay = az = 0.0
            if have_a:
                ax, ay, az = accel[i, 0] * TO_G, accel[i, 1] * TO_G, accel[i, 2] * TO_G
            r, at_rest = rest_update_kernel(r, p, gx, gy, gz, have_a, ax, ay, az, dts[i])
            state, gate_open, weight, bias = step(
                state, params, gx - r[9], gy - r[10], gz - r[11], have_a, ax, ay, az, use_m,
                mag[i, 0], mag[i, 1], mag[i, 2], dts[i], at_rest)
            if have_a and not gate_open:
                closed += 1
            diag[di, 0] = 1.0 if gate_open else 0.0
            diag[di, 1] = 1.0 if gate_open and use_m else 0.0
            diag[di, 2] = weight
            out[i, 0], out[i, 1], out[i, 2], out[i, 3] = state[0], state[1], state[2], state[3]
            diag[di, 3] = 1.0 if at_rest else 0.0
            diag[di, 4], diag[di, 5], diag[di, 6] = r[9], r[10], r[11]
            if with_bias:
                diag[di, 7], diag[di, 8], diag[di, 9] = bias[0], bias[1], bias[2]
        for k in range(12):
            rest[k] = r[k]
        return state, turn_sum, closed

    return jit(_ahrs_rows)
