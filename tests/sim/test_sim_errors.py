"""Sensor error models: statistics of long static runs match the configured spec.

Tolerances follow from the sample counts: the std of N Gaussian samples has a relative
standard error of 1/sqrt(2N); the mean of N samples, sigma/sqrt(N). Each tolerance below
is at least 5 of those standard errors (so a seeded run is far from the edge, yet a wrong
formula, e.g. a factor sqrt(2) in the noise bandwidth, fails).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from pydantic import ValidationError

from imuhal.emulation import PhysicalInputs
from imuhal.plugins.manager import load_registry
from imuhal.sim.errors import (
    MagErrorSpec,
    ScalarErrorSpec,
    SensorErrorModel,
    SensorErrorSpec,
    VectorErrorSpec,
    error_spec_of,
)
from imuhal_chips.mpu9250.emulator import MPU9250Emulator

LEVEL = PhysicalInputs(specific_force_m_s2=(0.0, 0.0, -9.80665),
                       angular_rate_rad_s=(0.0, 0.0, 0.0),
                       magnetic_field_ut=(39.9, -1.0, 9.2), pressure_pa=90_000.0,
                       temperature_degc=25.0)


def run(model: SensorErrorModel, n: int, period: float, inputs=LEVEL) -> list[PhysicalInputs]:
    return [model.apply(i * period, inputs, period) for i in range(n)]


def test_gyro_white_noise_std_is_density_times_root_nyquist_band():
    density, period, n = 0.01, 0.005, 20_000
    model = SensorErrorModel(SensorErrorSpec(gyro=VectorErrorSpec(noise_density=density)), 1)
    out = np.array([o.angular_rate_rad_s for o in run(model, n, period)])
    expected = density * math.sqrt(0.5 / period)          # 0.1 rad/s
    np.testing.assert_allclose(out.std(axis=0), expected, rtol=0.03)   # 1/sqrt(2N) = 0.5 %


def test_explicit_bandwidth_sets_the_noise_band():
    model = SensorErrorModel(SensorErrorSpec(
        accel=VectorErrorSpec(noise_density=0.003, bandwidth_hz=92.0)), 2)
    out = np.array([o.specific_force_m_s2 for o in run(model, 20_000, 0.001)])
    np.testing.assert_allclose(out.std(axis=0), 0.003 * math.sqrt(92.0), rtol=0.03)


def test_a_channel_period_given_per_channel_sets_that_channels_band():
    """``periods_s`` gives each channel its own sample period (the board passes the chip's
    per-channel output rates); channels not named use ``sample_period_s``."""
    density, n = 0.01, 20_000
    spec = SensorErrorSpec(gyro=VectorErrorSpec(noise_density=density),
                           accel=VectorErrorSpec(noise_density=density))
    model = SensorErrorModel(spec, 3)
    out = [model.apply_values(i * 0.01, (0.0, 0.0, 0.0), (0.0, 0.0, 0.0), None, None, None,
                              0.01, {"gyro": 0.0005}) for i in range(n)]
    gyro, accel = np.array([o[1] for o in out]), np.array([o[0] for o in out])
    np.testing.assert_allclose(gyro.std(axis=0), density * math.sqrt(1000.0), rtol=0.03)
    np.testing.assert_allclose(accel.std(axis=0), density * math.sqrt(50.0), rtol=0.03)
    assert model.period_channels == ("accel", "gyro")


def test_a_period_for_an_unknown_channel_is_refused():
    model = SensorErrorModel(SensorErrorSpec(gyro=VectorErrorSpec(noise_density=0.01)), 3)
    with pytest.raises(ValueError, match="unknown vector channel 'pressure'"):
        model.apply_values(0.0, None, (0.0, 0.0, 0.0), None, None, None, 0.01,
                           {"pressure": 0.01})


def test_only_density_channels_without_a_fixed_band_depend_on_the_period():
    model = SensorErrorModel(SensorErrorSpec(
        gyro=VectorErrorSpec(noise_density=0.01, bandwidth_hz=92.0),
        accel=VectorErrorSpec(noise_std=0.01),
        mag=MagErrorSpec(noise_density=0.1)), 3)
    assert model.period_channels == ("mag",)


def test_constant_bias_is_the_mean_of_a_static_run():
    bias = (0.02, -0.01, 0.005)
    model = SensorErrorModel(SensorErrorSpec(
        gyro=VectorErrorSpec(noise_density=0.01, bias=bias)), 3)
    out = np.array([o.angular_rate_rad_s for o in run(model, 20_000, 0.005)])
    # sigma 0.1 rad/s, N 20000: standard error 7e-4; tolerance 4e-3.
    np.testing.assert_allclose(out.mean(axis=0), bias, atol=4e-3)


def test_bias_random_walk_spreads_like_root_time():
    rw, seeds = 0.002, 400
    spec = SensorErrorSpec(gyro=VectorErrorSpec(bias_random_walk=rw))
    at_100, at_400 = [], []
    for seed in range(seeds):
        m = SensorErrorModel(spec, seed)
        for t in np.arange(0.0, 400.0 + 1e-9, 4.0):   # 101 steps of 4 s
            m.apply(float(t), LEVEL, 0.005)
            if t == 100.0:
                at_100.append(m.bias("gyro"))
        at_400.append(m.bias("gyro"))
    s100, s400 = np.std(at_100), np.std(at_400)
    # 1200 samples each: relative standard error of a std about 2 %; tolerance 10 %.
    assert s100 == pytest.approx(rw * math.sqrt(100.0), rel=0.10)
    assert s400 == pytest.approx(rw * math.sqrt(400.0), rel=0.10)
    assert s400 / s100 == pytest.approx(2.0, rel=0.12)


def test_scale_cross_axis_soft_and_hard_iron_form_the_documented_matrix():
    c = ((0.0, 0.01, -0.02), (0.005, 0.0, 0.0), (0.0, 0.03, 0.0))
    w = ((1.1, 0.05, 0.0), (0.05, 0.9, 0.0), (0.0, 0.0, 1.0))
    spec = MagErrorSpec(scale_factor_error=(0.02, -0.01, 0.0), cross_axis=c,
                        soft_iron=w, hard_iron_ut=(5.0, -3.0, 12.0))
    model = SensorErrorModel(SensorErrorSpec(mag=spec), 0)
    true = np.array(LEVEL.magnetic_field_ut)
    expected = np.array(w) @ (np.eye(3) + np.array(c)) @ np.diag([1.02, 0.99, 1.0]) @ true \
        + np.array([5.0, -3.0, 12.0])
    out = model.apply(0.0, LEVEL, 0.01).magnetic_field_ut
    np.testing.assert_allclose(out, expected, atol=1e-12)


def test_bias_follows_temperature_away_from_the_reference():
    spec = SensorErrorSpec(accel=VectorErrorSpec(bias_temp_coeff=(0.01, 0.0, -0.02),
                                                 reference_temperature_degc=25.0))
    model = SensorErrorModel(spec, 0)
    warm = PhysicalInputs(specific_force_m_s2=(0.0, 0.0, -9.8), temperature_degc=35.0)
    out = model.apply(0.0, warm, 0.01).specific_force_m_s2
    np.testing.assert_allclose(out, (0.1, 0.0, -9.8 - 0.2), atol=1e-12)


def test_scalar_noise_bias_and_drift():
    spec = SensorErrorSpec(pressure=ScalarErrorSpec(noise_std=1.2, bias=30.0,
                                                    drift_per_hour=36.0))
    model = SensorErrorModel(spec, 5)
    out = np.array([o.pressure_pa for o in run(model, 20_000, 0.025)]) - 90_000.0
    t = np.arange(20_000) * 0.025
    resid = out - (30.0 + 36.0 * t / 3600.0)
    assert resid.std() == pytest.approx(1.2, rel=0.03)
    assert abs(resid.mean()) < 0.05          # standard error 0.0085 Pa


def test_same_seed_same_output_other_seed_different():
    spec = error_spec_of(MPU9250Emulator)
    a = [o.angular_rate_rad_s for o in run(SensorErrorModel(spec, 11), 50, 0.005)]
    b = [o.angular_rate_rad_s for o in run(SensorErrorModel(spec, 11), 50, 0.005)]
    c = [o.angular_rate_rad_s for o in run(SensorErrorModel(spec, 12), 50, 0.005)]
    assert a == b
    assert a != c


def test_channels_draw_from_independent_streams():
    gyro = VectorErrorSpec(noise_density=0.01)
    only_gyro = SensorErrorModel(SensorErrorSpec(gyro=gyro), 4)
    with_mag = SensorErrorModel(SensorErrorSpec(gyro=gyro, mag=MagErrorSpec(noise_std=0.3)), 4)
    a = [o.angular_rate_rad_s for o in run(only_gyro, 20, 0.01)]
    b = [o.angular_rate_rad_s for o in run(with_mag, 20, 0.01)]
    assert a == b


def test_unmodelled_channels_pass_through_unchanged():
    model = SensorErrorModel(SensorErrorSpec(gyro=VectorErrorSpec(noise_density=0.01)), 0)
    out = model.apply(0.0, LEVEL, 0.01)
    assert out.specific_force_m_s2 == LEVEL.specific_force_m_s2
    assert out.pressure_pa == LEVEL.pressure_pa


def test_time_going_backwards_is_refused():
    model = SensorErrorModel(SensorErrorSpec(), 0)
    model.apply(1.0, LEVEL, 0.01)
    with pytest.raises(ValueError, match="backwards"):
        model.apply(0.5, LEVEL, 0.01)


def test_cross_axis_diagonal_is_rejected():
    with pytest.raises(ValidationError, match="zero diagonal"):
        VectorErrorSpec(cross_axis=((0.1, 0, 0), (0, 0, 0), (0, 0, 0)))


def test_every_installed_chip_emulator_declares_a_valid_error_spec():
    registry = load_registry()
    assert set(registry.emulators.names()) >= {"ms5611", "max21100", "max21105", "hmc5883l",
                                               "mpu9250", "ak8963", "bmp280"}
    for name in registry.emulators.names():
        if name == "gnss":
            continue  # a receiver's errors are its own GNSS model (imuhal_chips.gnss.emulator)
        assert isinstance(error_spec_of(registry.emulators.get(name)), SensorErrorSpec), name
    assert error_spec_of(registry.emulators.get("ms5611")).pressure.noise_std == \
        pytest.approx(1.2)


def test_an_emulator_without_a_spec_is_ideal():
    class Ideal:
        error_spec = None

    assert error_spec_of(Ideal) is None
