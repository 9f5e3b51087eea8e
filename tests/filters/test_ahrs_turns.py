"""Turn compensation: every AHRS holds the horizon in a coordinated turn given a speed.

In a steady banked turn the accelerometer reads g / cos(bank) straight down the body z axis,
so an uncompensated filter levels itself (tilt error = bank). With the kinematic acceleration
omega x v removed (nominal airspeed, an airspeed sensor or a velocity source), it must not.
"""

from __future__ import annotations

import math
from collections.abc import Iterator

import numpy as np
import pytest
from tests.filters.ahrs_cases import AHRS, FIELD_NED_UT, G0, make, run

from imuhal.core.frames import quat_from_euler_deg, quat_to_matrix
from imuhal.core.samples import (
    AccelSample,
    AirspeedSample,
    Frame,
    GyroSample,
    MagSample,
    Sample,
    VelocitySample,
)
from imuhal_filters.common.turn import KinematicAcceleration, TurnCompensationSettings

SPEED_M_S = 12.0
TURN_RAD_S = 2 * math.pi / 15.0  # a circle in 15 s: 27 deg of bank at 12 m/s
BANK_DEG = math.degrees(math.atan(SPEED_M_S * TURN_RAD_S / G0))
WIND_NE = (2.0, -1.0)


def _turn(seconds: float, *, airspeed: bool = False, velocity: bool = False
          ) -> Iterator[Sample | tuple[str, np.ndarray]]:
    """A steady right turn, 200 Hz IMU; optional 10 Hz airspeed or 5 Hz ground velocity
    (with wind). Also yields ("truth", q) before each gyro sample."""
    phi = math.radians(BANK_DEG)
    rate = (0.0, TURN_RAD_S * math.sin(phi), TURN_RAD_S * math.cos(phi))
    f_body = (0.0, 0.0, -math.hypot(G0, SPEED_M_S * TURN_RAD_S))
    for i in range(round(seconds * 200)):
        t = i * 5_000_000
        psi = TURN_RAD_S * t / 1e9
        q = quat_from_euler_deg(BANK_DEG, 0.0, math.degrees(psi))
        if velocity and i % 40 == 0:
            v = (SPEED_M_S * math.cos(psi) + WIND_NE[0], SPEED_M_S * math.sin(psi) + WIND_NE[1],
                 0.0)
            yield VelocitySample(t_ns=t, device="gnss", velocity_ned_m_s=v, accuracy_m_s=0.1)
        if airspeed and i % 20 == 0:
            yield AirspeedSample(t_ns=t, device="pitot", airspeed_m_s=SPEED_M_S)
        yield AccelSample(t_ns=t, device="imu", frame=Frame.BODY_NED, accel_m_s2=f_body)
        yield MagSample(t_ns=t, device="mag", frame=Frame.BODY_NED,
                        mag_ut=tuple(quat_to_matrix(q).T @ FIELD_NED_UT))
        yield ("truth", q)
        yield GyroSample(t_ns=t, device="imu", frame=Frame.BODY_NED, gyro_rad_s=rate)


def _worst_late_tilt(name: str, settings: dict, seconds: float = 20.0, **source: bool
                     ) -> float:
    est = make(name, settings)
    truth: dict[int, np.ndarray] = {}
    pending = None
    samples: list[Sample] = []
    for item in _turn(seconds, **source):
        if isinstance(item, tuple):
            pending = item[1]
            continue
        if isinstance(item, GyroSample):
            truth[item.t_ns] = pending
        samples.append(item)
    worst = 0.0
    for e in run(est, iter(samples)):
        if e.t_ns >= (seconds - 5.0) * 1e9:
            d_est = quat_to_matrix(np.asarray(e.q_body_to_ned))[2]
            d_true = quat_to_matrix(truth[e.t_ns])[2]
            worst = max(worst, math.degrees(math.acos(min(1.0, float(d_est @ d_true)))))
    return worst


@pytest.mark.parametrize("name", list(AHRS))
def test_without_a_speed_the_turn_levels_the_filter(name: str) -> None:
    if name == "imufilter":
        pytest.skip("imufilter's accel band already distrusts the 1.13 g it reads here")
    assert _worst_late_tilt(name, {}) > 0.5 * BANK_DEG


@pytest.mark.parametrize("name", list(AHRS))
def test_nominal_airspeed_holds_the_horizon(name: str) -> None:
    assert _worst_late_tilt(name, {"nominal_airspeed_m_s": SPEED_M_S}) < 1.0


@pytest.mark.parametrize("name", ["madgwick", "freescale-6dof"])
def test_airspeed_samples_hold_the_horizon(name: str) -> None:
    assert _worst_late_tilt(name, {}, airspeed=True) < 1.0


@pytest.mark.parametrize("name", ["mahony", "freescale-9dof"])
def test_ground_velocity_with_wind_holds_the_horizon_once_a_circle_is_flown(name: str) -> None:
    """Until the first circle has shown the wind, the ground speed's swing is taken for
    acceleration and tilts the filter by a few degrees; the filters' soft gates then weigh
    the accelerometer by how far it disagrees with the attitude, so the tilt comes back over
    the following circles (mahony: 1.7 deg at 20 s, 0.8 at 40 s, 0.35 at 60 s)."""
    assert _worst_late_tilt(name, {}, seconds=40.0, velocity=True) < 1.0


def test_the_wind_and_airspeed_come_from_circling_ground_velocities() -> None:
    kin = KinematicAcceleration(TurnCompensationSettings())
    for item in _turn(16.0, velocity=True):
        if isinstance(item, VelocitySample):
            kin.on_velocity(item)
        elif isinstance(item, GyroSample):
            kin.step(item.t_ns, item.gyro_rad_s)
    assert kin.wind_ne_m_s == pytest.approx(WIND_NE, abs=0.05)
    assert kin.step(None, (0.0, 0.0, 0.1)) == pytest.approx((0.0, 0.1 * SPEED_M_S, 0.0),
                                                            abs=0.05)
    assert kin.source == "velocity"


def test_turn_compensation_off_ignores_every_source() -> None:
    kin = KinematicAcceleration(TurnCompensationSettings(turn_compensation=False,
                                                         nominal_airspeed_m_s=10.0))
    assert kin.step(0, (0.0, 0.0, 0.3)) == (0.0, 0.0, 0.0)
    assert kin.source == "off"


@pytest.mark.parametrize("name", ["madgwick", "freescale-9dof"])
def test_state_with_a_velocity_source_round_trips_through_json(name: str) -> None:
    import json

    samples = [s for s in _turn(14.0, velocity=True) if not isinstance(s, tuple)]
    cut = len(samples) // 2
    straight, first = make(name), make(name)
    whole = run(straight, iter(samples))
    head = run(first, iter(samples[:cut]))
    resumed = make(name)
    resumed.set_state(json.loads(json.dumps(first.get_state())))
    tail = run(resumed, iter(samples[cut:]))
    assert [e.q_body_to_ned for e in head + tail] == [e.q_body_to_ned for e in whole]
