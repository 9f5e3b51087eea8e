"""Error models planned ahead (``SensorErrorModel.plan_values``): n coming calls in one numpy
pass give the same floats, bit for bit, as the same calls one after another, and the model
stands after the calls taken exactly as after those calls made one by one."""

from __future__ import annotations

import numpy as np
import pytest

from imuhal.sim.errors import SensorErrorModel, SensorErrorSpec

# Every kind of error on every channel: turn-on draws, random walks, temperature terms,
# noise by density (period-dependent) and by std, hard and soft iron, drift.
SPEC = SensorErrorSpec.model_validate({
    "accel": {"noise_density": 2e-3, "bias_std": 0.2, "bias_random_walk": 1e-3,
              "bias_temp_coeff": (0.003, -0.002, 0.005), "scale_factor_std": 0.01,
              "cross_axis_std": 0.005},
    "gyro": {"noise_density": 1e-4, "noise_std": 2e-4, "bias_std": 0.01,
             "bias_random_walk": 1e-5, "bias_temp_coeff": (1e-4, 2e-4, -1e-4)},
    "mag": {"noise_std": 0.3, "bandwidth_hz": 50.0, "hard_iron_ut": (3.0, -2.0, 1.0),
            "soft_iron": ((1.02, 0.01, 0.0), (0.01, 0.98, 0.0), (0.0, 0.0, 1.0))},
    "pressure": {"noise_std": 2.0, "bias_std": 30.0, "drift_per_hour": 5.0,
                 "random_walk": 0.5, "temp_coeff": 1.5},
    "temperature": {"noise_std": 0.02, "bias_std": 1.0},
})
PERIODS = {"accel": 0.004, "gyro": 0.004}


def _calls(n: int, seed: int = 3) -> tuple[np.ndarray, ...]:
    """n calls: times with repeats (two reads of one instant) and uneven steps, and
    varying true values."""
    rng = np.random.default_rng(seed)
    steps = rng.choice([0, 4_000_000, 4_000_000, 8_000_000], size=n)
    t_ns = 1_000_000_000 + np.cumsum(steps)
    t_s = t_ns / 1e9
    return (t_s, rng.normal(0.0, 9.0, (n, 3)), rng.normal(0.0, 1.0, (n, 3)),
            rng.normal(20.0, 10.0, (n, 3)), rng.normal(95_000.0, 50.0, n),
            rng.normal(30.0, 5.0, n))


def _one_by_one(model: SensorErrorModel, calls: tuple[np.ndarray, ...], rows: range
                ) -> list[tuple[object, ...]]:
    t_s, accel, gyro, mag, pressure, temp = calls
    return [model.apply_values(float(t_s[i]), tuple(accel[i].tolist()),
                               tuple(gyro[i].tolist()), tuple(mag[i].tolist()),
                               float(pressure[i]), float(temp[i]), 0.01, PERIODS)
            for i in rows]


def _planned_rows(plan, rows: range) -> list[tuple[object, ...]]:
    accel, gyro, mag, pressure, temp = plan.values
    return [(tuple(accel[i].tolist()), tuple(gyro[i].tolist()), tuple(mag[i].tolist()),
             float(pressure[i]), float(temp[i])) for i in rows]


def test_planned_calls_give_the_floats_of_the_calls_one_by_one():
    calls = _calls(600)
    planned = SensorErrorModel(SPEC, seed=7)
    plan = planned.plan_values(*calls, 0.01, PERIODS)
    assert plan is not None
    assert _planned_rows(plan, range(600)) == _one_by_one(SensorErrorModel(SPEC, seed=7),
                                                          calls, range(600))


@pytest.mark.parametrize("taken", [0, 1, 137, 600])
def test_after_taking_some_planned_calls_the_model_goes_on_as_after_those_calls(taken):
    calls = _calls(600)
    reference = SensorErrorModel(SPEC, seed=11)
    expected = _one_by_one(reference, calls, range(600))
    model = SensorErrorModel(SPEC, seed=11)
    plan = model.plan_values(*calls, 0.01, PERIODS)
    plan.used = taken
    assert _one_by_one(model, calls, range(taken, 600)) == expected[taken:]


def test_a_new_plan_starts_where_the_calls_taken_from_the_previous_one_left_off():
    calls = _calls(400)
    expected = _one_by_one(SensorErrorModel(SPEC, seed=5), calls, range(400))
    model = SensorErrorModel(SPEC, seed=5)
    model.plan_values(*calls, 0.01, PERIODS).used = 150
    rest = tuple(c[150:] for c in calls)
    plan = model.plan_values(*rest, 0.01, PERIODS)
    assert _planned_rows(plan, range(250)) == expected[150:]


def test_the_bias_read_after_planned_calls_is_the_bias_after_them():
    calls = _calls(300)
    reference = SensorErrorModel(SPEC, seed=2)
    _one_by_one(reference, calls, range(120))
    model = SensorErrorModel(SPEC, seed=2)
    model.plan_values(*calls, 0.01, PERIODS).used = 120
    assert model.bias("accel", 25.0) == reference.bias("accel", 25.0)
    assert model.bias("pressure", 25.0) == reference.bias("pressure", 25.0)


def test_calls_before_the_last_one_made_are_not_planned():
    calls = _calls(10)
    model = SensorErrorModel(SPEC, seed=1)
    _one_by_one(model, calls, range(5))
    earlier = (calls[0][:3] - 1.0, *(c[:3] for c in calls[1:]))
    assert model.plan_values(*earlier, 0.01, PERIODS) is None


BARO_SPEC = SensorErrorSpec.model_validate({
    "pressure": {"noise_std": 1.2, "bias_std": 50.0, "drift_per_hour": 3.0,
                 "random_walk": 0.4, "temp_coeff": 0.5},
    "temperature": {"noise_std": 0.002, "bias_std": 0.3},
})


def test_a_barometer_model_applied_later_gives_the_floats_of_the_call_made_then():
    calls = _calls(300)
    t_s, _, _, _, pressure, temp = calls
    reference = SensorErrorModel(BARO_SPEC, seed=4)
    expected = [reference.apply_values(float(t_s[i]), None, None, None, float(pressure[i]),
                                       float(temp[i]), 0.01)[3:] for i in range(300)]
    model = SensorErrorModel(BARO_SPEC, seed=4)
    halves = [model.apply_later(float(t)) for t in t_s]
    # finished in another order, after every later call was made
    got = [halves[i](float(pressure[i]), float(temp[i])) for i in reversed(range(300))]
    assert got[::-1] == expected


def test_a_model_with_a_vector_channel_is_not_applied_later():
    assert SensorErrorModel(SPEC, seed=1).apply_later(1.0) is None
