"""Mahony's complementary AHRS as a pure per-step function (plain floats, float64).

This is the filter of the seed author's ESP32 vario firmware (har-in-air/ESP32_IMU_BARO_GPS_VARIO,
``src/sensor/imu.cpp``: Madgwick's x-io implementation of Mahony's algorithm, modified to take
a "use accelerometer" flag). Conventions as the x-io code in NED: quaternion (w, x, y, z)
rotating body -> NED, gyro rad/s, accelerometer gravity positive (any unit, normalised),
magnetometer any unit (normalised).

One step: the error ``e`` is the cross product of the measured and the predicted directions of
gravity (and, with a magnetometer, of the earth field); the gyro is corrected by
``Kp e + integral`` with ``integral += Ki e dt``, then ``q <- normalise(q + 0.5 q (0, w) dt)``.
When the accelerometer is not used (``accel`` None, e.g. the gate is closed) there is no
feedback at all: neither the magnetometer term nor the integral is applied, exactly as in the
firmware. With ``Ki == 0`` the integral is held at zero (the firmware's anti-windup).

Unlike the x-io Madgwick release, the field reference here is formed as the paper intends
(``b_x = |2 h_xy|``, ``b_z = 2 h_z`` with the half-vector algebra), so no factor of two is lost.
"""

from __future__ import annotations

import math

from imuhal_filters.common.quat import Quat, Vec


def _unit(v: Vec) -> Vec | None:
    n = math.sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2])
    if n == 0.0 or not math.isfinite(n):
        return None
    return (v[0] / n, v[1] / n, v[2] / n)


def mahony_error(q: Quat, accel: Vec, mag: Vec | None) -> Vec:
    """Half the feedback error (the firmware's ``halfe``) for normalised ``accel`` and ``mag``."""
    q0, q1, q2, q3 = q
    ax, ay, az = accel
    # predicted gravity direction (half): third row of R(q)
    hvx = q1 * q3 - q0 * q2
    hvy = q0 * q1 + q2 * q3
    hvz = q0 * q0 - 0.5 + q3 * q3
    ex = ay * hvz - az * hvy
    ey = az * hvx - ax * hvz
    ez = ax * hvy - ay * hvx
    if mag is not None:
        mx, my, mz = mag
        q11, q22, q33 = q1 * q1, q2 * q2, q3 * q3
        hx = 2.0 * (mx * (0.5 - q22 - q33) + my * (q1 * q2 - q0 * q3) + mz * (q1 * q3 + q0 * q2))
        hy = 2.0 * (mx * (q1 * q2 + q0 * q3) + my * (0.5 - q11 - q33) + mz * (q2 * q3 - q0 * q1))
        bx = math.sqrt(hx * hx + hy * hy)
        bz = 2.0 * (mx * (q1 * q3 - q0 * q2) + my * (q2 * q3 + q0 * q1) + mz * (0.5 - q11 - q22))
        # predicted field direction (half), body frame
        hwx = bx * (0.5 - q22 - q33) + bz * (q1 * q3 - q0 * q2)
        hwy = bx * (q1 * q2 - q0 * q3) + bz * (q0 * q1 + q2 * q3)
        hwz = bx * (q0 * q2 + q1 * q3) + bz * (0.5 - q11 - q22)
        ex += my * hwz - mz * hwy
        ey += mz * hwx - mx * hwz
        ez += mx * hwy - my * hwx
    return (ex, ey, ez)


def mahony_step(
    q: Quat,
    integral: Vec,
    gyro_rad_s: Vec,
    accel: Vec | None,
    mag: Vec | None,
    kp: float,
    ki: float,
    dt_s: float,
) -> tuple[Quat, Vec]:
    """One Mahony step; returns (new quaternion, new integral feedback in rad/s).

    ``accel`` None (or zero) means no feedback this step; ``mag`` None (or zero) is the 6-DOF
    update. ``kp``, ``ki`` are the gains (the firmware stores twice these, ``twoKp``/``twoKi``).
    """
    gx, gy, gz = gyro_rad_s
    a = None if accel is None else _unit(accel)
    if a is not None:
        m = None if mag is None else _unit(mag)
        ex, ey, ez = mahony_error(q, a, m)
        if ki > 0.0:
            ix, iy, iz = integral
            integral = (ix + 2.0 * ki * ex * dt_s, iy + 2.0 * ki * ey * dt_s,
                        iz + 2.0 * ki * ez * dt_s)
            gx, gy, gz = gx + integral[0], gy + integral[1], gz + integral[2]
        else:
            integral = (0.0, 0.0, 0.0)
        gx, gy, gz = gx + 2.0 * kp * ex, gy + 2.0 * kp * ey, gz + 2.0 * kp * ez
    h = 0.5 * dt_s
    gx, gy, gz = gx * h, gy * h, gz * h
    q0, q1, q2, q3 = q
    w = q0 + (-q1 * gx - q2 * gy - q3 * gz)
    x = q1 + (q0 * gx + q2 * gz - q3 * gy)
    y = q2 + (q0 * gy - q1 * gz + q3 * gx)
    z = q3 + (q0 * gz + q1 * gy - q2 * gx)
    r = 1.0 / math.sqrt(w * w + x * x + y * y + z * z)
    return (w * r, x * r, y * r, z * r), integral
