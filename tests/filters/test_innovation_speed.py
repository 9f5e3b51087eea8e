"""The accelerometer innovation integrated into a speed (imuhal_filters.common.innovation):
what it lets through and what it gates, on plain vectors (g, gravity positive, 100 Hz; the
speed leaks over 1 s, bound 1 m/s, the innovation's own mean over 3 s taken out)."""

from __future__ import annotations

import math

from imuhal_filters.common.innovation import InnovationSpeed

DT_S = 0.01
UP = (0.0, 0.0, 1.0)


def _inn() -> InnovationSpeed:
    return InnovationSpeed(tau_s=1.0, speed_m_s=1.0, mean_tau_s=3.0)


def _weights(readings: list[tuple[float, float, float]], inn: InnovationSpeed) -> list[float]:
    return [inn.weight(r, UP, DT_S) for r in readings]


def test_without_a_gravity_estimate_every_reading_counts_in_full() -> None:
    assert _inn().weight((0.5, 0.0, 1.0), None, DT_S) == 1.0


def test_a_sudden_acceleration_across_gravity_is_gated_within_a_second() -> None:
    # 0.3 g sideways: a loop's pull or a turn entered without a speed source
    w = _weights([(0.3, 0.0, 1.0)] * 100, _inn())
    assert w[0] > 0.99
    assert w[-1] < 0.3


def test_an_acceleration_along_gravity_does_not_gate() -> None:
    # a lift or a pull straight up: it cannot tilt the estimate
    w = _weights([(0.0, 0.0, 1.5)] * 200, _inn())
    assert min(w) > 0.999


def test_a_hand_shaking_the_board_keeps_most_of_the_weight() -> None:
    # 5 cm at 1 Hz: 0.31 m/s peak speed, 0.2 g peak acceleration, back and forth
    omega = 2 * math.pi
    readings = [(0.05 * omega * omega * math.sin(omega * i * DT_S) / 9.80665, 0.0, 1.0)
                for i in range(500)]
    assert min(_weights(readings, _inn())) > 0.75


def test_an_acceleration_turning_with_the_vehicle_stays_gated() -> None:
    # a 20 s circle's centripetal acceleration (0.3 g) turns round in the almost-inertial
    # frame: its mean never settles, so it is never taken for a tilt error
    omega = 2 * math.pi / 20.0
    readings = [(0.3 * math.cos(omega * i * DT_S), 0.3 * math.sin(omega * i * DT_S), 1.0)
                for i in range(4000)]
    assert max(_weights(readings, _inn())[1000:]) < 0.3


def test_a_constant_innovation_is_a_tilt_error_and_is_trusted_after_a_few_seconds() -> None:
    # a 10 deg tilt error shows as a constant innovation of sin(10 deg) g, held in one
    # direction for longer than any vehicle accelerates one way: the filter must correct it
    error = (math.sin(math.radians(10.0)), 0.0, math.cos(math.radians(10.0)))
    w = _weights([error] * 2000, _inn())
    assert w[100] < 0.6
    assert w[-1] > 0.95


def test_rest_resets_the_speed() -> None:
    inn = _inn()
    _weights([(0.3, 0.0, 1.0)] * 50, inn)
    inn.reset()
    assert inn.v_m_s == [0.0, 0.0, 0.0]
    assert inn.weight((0.0, 0.0, 1.0), UP, DT_S) > 0.999
