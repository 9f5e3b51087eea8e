"""Every scenario's truth is kinematically consistent: the body rate integrates to the
attitude and specific force plus gravity integrates to velocity and position.

Integration: RK4 at 10 ms over the whole default run, from the true initial state.
Tolerances: attitude 1e-5 rad (2 arcsec), velocity 1e-4 m/s, position 1e-3 m.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from imuhal.sim.builtin import BUILTIN_SCENARIOS
from imuhal.sim.world import MotionScenario

SCENARIOS = [c for c in BUILTIN_SCENARIOS if c.name != "replay"]


@pytest.mark.parametrize("cls", SCENARIOS, ids=[c.name for c in SCENARIOS])
def test_truth_integrates_consistently_over_the_whole_run(cls, consistency):
    scenario: MotionScenario = cls(seed=7)
    g = scenario.environment.gravity_m_s2
    err = consistency(scenario.kinematics, scenario.duration_s, 0.01, g)
    assert err.attitude_rad < 1e-5
    assert err.velocity_m_s < 1e-4
    assert err.position_m < 1e-3


@pytest.mark.parametrize("cls", SCENARIOS, ids=[c.name for c in SCENARIOS])
def test_truth_state_matches_the_kinematics_it_is_built_from(cls):
    scenario: MotionScenario = cls(seed=3)
    for t in np.linspace(0.0, scenario.duration_s, 7):
        k = scenario.kinematics(float(t))
        s = scenario.truth(float(t))
        r = np.array(k.rotation).reshape(3, 3)
        np.testing.assert_allclose(s.q_body_to_ned, k.q_body_to_ned, atol=1e-15)
        assert math.isclose(float(np.linalg.norm(s.q_body_to_ned)), 1.0, abs_tol=1e-12)
        # Specific force is R^T (a - g): reconstruct a from it.
        a = r @ s.specific_force_body_m_s2 + np.array([0, 0, scenario.environment.gravity_m_s2])
        np.testing.assert_allclose(a, k.acceleration_ned_m_s2, atol=1e-9)
        assert s.altitude_m == pytest.approx(-k.position_ned_m[2])
        assert s.climb_m_s == pytest.approx(-k.velocity_ned_m_s[2])


def test_a_long_run_keeps_a_bounded_position_table_and_the_same_positions():
    """Issue 9 item 10."""
    from imuhal.sim.motion import FlightMotion
    from imuhal.sim.signals import Signal

    def glider() -> FlightMotion:
        yaw = Signal().rate_step(5.0, 2.0, 0.2)
        return FlightMotion(yaw=yaw, speed_along_heading=Signal(10.0))

    forward = glider()
    along = [forward.kinematics(t).position_ned_m for t in range(0, 600, 3)]
    # ten minutes of 0.01 s nodes: a bounded number kept (not 60 000)
    kept = sum(len(seg[0]) for seg in forward._segments.values())
    assert kept <= 5 * 1025
    backward = glider()
    late_first = [backward.kinematics(t).position_ned_m for t in reversed(range(0, 600, 3))]
    assert list(reversed(late_first)) == along
