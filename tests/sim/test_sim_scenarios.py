"""Scenario behaviour: registration, parameters, determinism and what each one promises."""

from __future__ import annotations

import math

import numpy as np
import pytest
from pydantic import ValidationError

from imuhal.plugins.manager import load_registry
from imuhal.sim.builtin import BUILTIN_SCENARIOS
from imuhal.sim.calibration import CalibrationScenario
from imuhal.sim.elevator import ElevatorScenario
from imuhal.sim.environment import Environment
from imuhal.sim.magnet import MagnetScenario
from imuhal.sim.rc_flight import RcFlightScenario
from imuhal.sim.static import StaticScenario
from imuhal.sim.thermal import ThermalScenario

G = 9.80665


def test_all_scenarios_are_registered_by_name_through_the_plugin_hook():
    names = load_registry().scenarios.names()
    for expected in ("static", "calibration", "tumble", "thermal", "rc-flight", "magnet",
                     "elevator", "replay"):
        assert expected in names


@pytest.mark.parametrize("cls", BUILTIN_SCENARIOS, ids=[c.name for c in BUILTIN_SCENARIOS])
def test_every_scenario_documents_its_parameters(cls):
    assert cls.description
    for name, field in cls.Params.model_fields.items():
        assert field.description or field.annotation is not None, name
    assert cls.default_duration_s >= 0


def test_params_override_by_dict_and_unknown_keys_are_rejected():
    s = StaticScenario({"yaw_deg": 90.0, "environment": {"gravity_m_s2": 9.78}})
    yaw = s.truth(1.0).euler_deg[2]
    assert yaw == pytest.approx(90.0)
    np.testing.assert_allclose(s.truth(1.0).specific_force_body_m_s2, (0, 0, -9.78),
                               atol=1e-12)
    with pytest.raises(ValidationError):
        StaticScenario({"yaw": 90.0})


def test_static_board_at_rest_reads_minus_g_and_the_earth_field():
    s = StaticScenario()
    t = s.truth(12.0)
    np.testing.assert_allclose(t.specific_force_body_m_s2, (0, 0, -G), atol=1e-12)
    np.testing.assert_allclose(t.angular_rate_body_rad_s, 0.0, atol=0)
    np.testing.assert_allclose(t.magnetic_field_body_ut,
                               s.environment.magnetic_field_ned_ut(), atol=1e-12)


def _g_range(scenario, step=0.01):
    ts = np.arange(0.0, scenario.duration_s, step)
    mags = np.array([math.sqrt(sum(c * c for c in scenario.kinematics(float(t))
                                   .specific_force_body_m_s2)) for t in ts]) / G
    return mags.min(), mags.max()


def test_rc_flight_leaves_the_gated_madgwick_window_both_ways():
    lo, hi = _g_range(RcFlightScenario(seed=0))
    assert lo < 0.6
    assert hi > 1.4


def test_thermal_stays_near_one_g_for_the_gate():
    lo, hi = _g_range(ThermalScenario(seed=0), step=0.05)
    assert lo > 0.6 and hi < 1.4


@pytest.mark.parametrize("name", ["thermal", "rc-flight", "tumble", "magnet"])
def test_same_seed_same_truth_other_seed_different(name):
    cls = load_registry().scenarios.get(name)
    a, b, c = cls(seed=5), cls(seed=5), cls(seed=6)
    t = 0.8 * a.duration_s             # inside every scenario's seeded part
    np.testing.assert_array_equal(a.truth(t).q_body_to_ned, b.truth(t).q_body_to_ned)
    np.testing.assert_array_equal(a.truth(t).magnetic_field_body_ut,
                                  b.truth(t).magnetic_field_body_ut)
    ta, tc = a.truth(t), c.truth(t)
    assert not (np.array_equal(ta.q_body_to_ned, tc.q_body_to_ned)
                and np.array_equal(ta.magnetic_field_body_ut, tc.magnetic_field_body_ut))


def test_truth_is_a_pure_function_of_time_whatever_the_query_order():
    a, b = ThermalScenario(seed=2), ThermalScenario(seed=2)
    late = a.truth(50.0)               # a builds its position table out of order
    for t in np.arange(0.0, 50.0, 0.37):
        b.truth(float(t))
    np.testing.assert_array_equal(late.position_ned_m, b.truth(50.0).position_ned_m)


def test_thermal_keeps_the_scheduled_climb_rates():
    s = ThermalScenario({"gust_rms_m_s": 0.0, "pendulum_rms_deg": 0.0})
    for t, climb in [(3.0, 0.0), (10.0, -1.1), (25.0, 2.5), (38.0, -3.0), (50.0, 1.2)]:
        assert s.truth(t).climb_m_s == pytest.approx(climb, abs=1e-12)
    # Closed form: still until 5 s, then a raised-cosine change to -1.1 m/s over 3 s
    # (which loses half the transition), then a steady glide until 15 s.
    assert s.truth(15.0).altitude_m == pytest.approx(-1.1 * 10.0 + 1.1 * 3.0 / 2, abs=1e-9)


def test_thermal_turns_are_coordinated():
    s = ThermalScenario({"gust_rms_m_s": 0.0, "pendulum_rms_deg": 0.0})
    t = s.truth(25.0)                          # mid-thermal, constant turn
    roll = t.euler_deg[0]
    turn_rate = 2 * math.pi / 20.0
    assert roll == pytest.approx(math.degrees(math.atan(10.0 * turn_rate / G)), abs=1e-6)
    assert abs(t.specific_force_body_m_s2[1]) < 1e-9  # no side force
    assert abs(t.angular_rate_body_rad_s @ [0, 0, 1]) > 0.25


def test_calibration_holds_each_axis_down_still():
    s = CalibrationScenario()
    holds = [p for p in s.phases() if p.name.endswith("down")]
    assert len(holds) == 6
    for ph in holds:
        sign = 1.0 if ph.name[0] == "+" else -1.0
        axis = "xyz".index(ph.name[1])
        for t in np.linspace(ph.start_s, ph.end_s, 5):
            tr = s.truth(float(t))
            # The axis pointing down reads -g in specific force.
            expected = np.zeros(3)
            expected[axis] = -sign * G
            np.testing.assert_allclose(tr.specific_force_body_m_s2, expected, atol=1e-9)
            np.testing.assert_allclose(tr.angular_rate_body_rad_s, 0.0, atol=1e-12)


@pytest.mark.parametrize("site", ["bangalore", "mid-latitude"])
def test_calibration_figure_eight_sweeps_the_field_over_the_sphere(site):
    s = CalibrationScenario({"environment": Environment.preset(site).model_dump()})
    (fig8,) = [p for p in s.phases() if p.name == "figure-8"]
    m = np.array([s.truth(float(t)).magnetic_field_body_ut
                  for t in np.arange(fig8.start_s, fig8.end_s, 0.05)])
    b = np.linalg.norm(s.environment.magnetic_field_ned_ut())
    # Every body axis sees most of the +-|B| range, as min/max calibration needs.
    assert np.all(m.max(axis=0) > 0.8 * b)
    assert np.all(m.min(axis=0) < -0.8 * b)


def test_magnet_disturbance_truth_is_the_field_minus_the_earth_field():
    s = MagnetScenario()
    earth = s.environment.magnetic_field_ned_ut()
    peaks = []
    for ph in [p for p in s.phases() if p.name.startswith("magnet pass")]:
        mid = 0.5 * (ph.start_s + ph.end_s)
        tr = s.truth(mid)
        r = np.array(s.kinematics(mid).rotation).reshape(3, 3)
        np.testing.assert_allclose(tr.magnetic_field_body_ut,
                                   r.T @ (earth + tr.magnetic_disturbance_ned_ut), atol=1e-9)
        peaks.append(np.linalg.norm(tr.magnetic_disturbance_ned_ut))
    # Dipole: 0.1 uT * m / d^3 * (1..2); the closest pass (1 A m^2 at 6 cm) is hundreds of uT.
    assert 1.5 < peaks[0] < 60.0
    assert peaks[2] > 400.0


def test_elevator_moves_only_vertically():
    s = ElevatorScenario()
    alts = []
    for t in np.arange(0.0, s.duration_s, 0.5):
        tr = s.truth(float(t))
        np.testing.assert_allclose(tr.position_ned_m[:2], 0.0, atol=0)
        np.testing.assert_allclose(tr.angular_rate_body_rad_s, 0.0, atol=0)
        alts.append(tr.altitude_m)
    assert max(alts) == pytest.approx(4 * 3.2)
    assert s.truth(s.duration_s).altitude_m == pytest.approx(0.0, abs=1e-9)


@pytest.mark.parametrize("name", ["thermal", "rc-flight", "magnet", "calibration"])
def test_chip_truth_gives_the_same_floats_as_truth_and_the_light_one_skips_the_attitude(name):
    # The emulated board reads the plain-float chip truth at every poll; a barometer gets the
    # light one. Both must be truth() to the last bit, or a speed-up changes every run.
    scenario = load_registry().scenarios.get(name)(None, seed=3)
    for t in (0.0, 0.0137, 7.3, 41.004, scenario.duration_s * 0.9):
        full = scenario.truth(t)
        chip = scenario.chip_truth(t)
        light = scenario.chip_truth(t, motion=False)
        for got, want in ((chip.specific_force_body_m_s2, full.specific_force_body_m_s2),
                          (chip.angular_rate_body_rad_s, full.angular_rate_body_rad_s),
                          (chip.magnetic_field_body_ut, full.magnetic_field_body_ut),
                          (chip.position_ned_m, full.position_ned_m),
                          (chip.velocity_ned_m_s, full.velocity_ned_m_s),
                          (light.position_ned_m, full.position_ned_m)):
            assert got == tuple(want.tolist())
        for truth in (chip, light):
            assert (truth.pressure_pa, truth.temperature_degc) == (full.pressure_pa,
                                                                   full.temperature_degc)
        assert light.specific_force_body_m_s2 is None and light.velocity_ned_m_s is None


def test_chip_truth_of_a_scenario_that_overrides_truth_reads_its_truth():
    # A plugin's scenario adds its own quantities by overriding truth(); the emulated board's
    # per-poll chip truth must carry them too.
    from dataclasses import replace

    class Humid(StaticScenario):
        def truth(self, t_s):
            return replace(super().truth(t_s), other={"humidity": 40.0 + t_s})

    assert Humid(seed=0).chip_truth(2.5).other == {"humidity": 42.5}
