"""vario-kf3 against ground truth: what the seed claims the accelerometer buys.

Data set C (first 50 s: 5 s at rest, glide, sink, entry into a thermal), 40 Hz, baro noise
0.30 m, accel noise 0.10 m/s^2, bias 0.15-0.18 m/s^2. Errors are scored from t = 5 s, as in
the conformance README. The step-climb scenario is synthetic and seeded.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from imuhal_filters.vario.batch import run_baro_batch, run_batch

DATA = Path(__file__).resolve().parent.parent / "data" / "filters"
DT_S = 0.025
SETTLED = 200  # rows: the first 5 s

# The barometer-only filter at its best on this data (sigma_a swept 0.1..12 m/s^2: the
# climb-rate error is smallest near 3), so the comparison is not against a straw man.
BARO_TUNED = {"accel_noise_m_s2": 3.0, "altitude_noise_m": 0.3}
ESP32 = {"preset": "reference"}
"""The esp32 reference tuning, whose figures the bounds below quote (data set C's barometer
is noisier than the seed boards' that the defaults are tuned for)."""


def _flight() -> np.ndarray:
    return np.genfromtxt(DATA / "vario_C_first50s.csv", delimiter=",", names=True)


def _rms(x: np.ndarray) -> float:
    return float(np.sqrt(np.mean(x**2)))


def test_kf3_climb_rate_error_is_well_below_the_barometer_only_filter() -> None:
    d = _flight()
    z, a, v_true = d["z_baro_cm"] / 100, d["a_meas_cms2"] / 100, d["v_true_cms"] / 100
    kf3 = run_batch(z, a, DT_S, ESP32)
    baro = run_baro_batch(z, DT_S, BARO_TUNED)
    kf3_rms = _rms((kf3.climb_m_s - v_true)[SETTLED:])
    baro_rms = _rms((baro.climb_m_s - v_true)[SETTLED:])
    # measured: kf3 (esp32 defaults) 0.19 m/s, tuned barometer-only 0.33 m/s
    assert kf3_rms < 0.22
    assert kf3_rms < 0.7 * baro_rms


def test_kf3_altitude_error_is_a_third_of_the_raw_barometer_noise() -> None:
    d = _flight()
    z, z_true = d["z_baro_cm"] / 100, d["z_true_cm"] / 100
    kf3 = run_batch(z, d["a_meas_cms2"] / 100, DT_S, ESP32)
    raw_rms = _rms((z - z_true)[SETTLED:])
    assert 0.25 < raw_rms < 0.35  # the data is what the README says
    assert _rms((kf3.altitude_m - z_true)[SETTLED:]) < raw_rms / 3


def test_accel_bias_converges_to_the_true_bias_within_5_cm_s2_rms() -> None:
    d = _flight()
    kf3 = run_batch(d["z_baro_cm"] / 100, d["a_meas_cms2"] / 100, DT_S, ESP32)
    assert kf3.accel_bias_m_s2 is not None
    error = kf3.accel_bias_m_s2 - d["bias_true_cms2"] / 100
    # starts at 0 against a true 0.15 m/s^2; after the 5 s static start it tracks the slowly
    # varying bias (measured: 0.034 m/s^2 RMS, mean within 0.01)
    assert abs(error[0]) > 0.1
    assert _rms(error[SETTLED:]) < 0.05
    assert abs(float(np.mean(error[SETTLED:]))) < 0.02


def _step_climb(seed: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, float]:
    """15 s at rest, then 4 m/s^2 for 0.5 s into a steady 2 m/s climb; 40 Hz, baro noise
    0.3 m, accel bias 0.15 m/s^2 and noise 0.1 m/s^2 (the data set C sensor model)."""
    rng = np.random.default_rng(seed)
    n = int(30.0 / DT_S)
    t = np.arange(n) * DT_S
    t_step = 15.0
    accel = np.where((t >= t_step - 1e-9) & (t < t_step + 0.5 - 1e-9), 4.0, 0.0)
    v = np.concatenate([[0.0], np.cumsum(accel[:-1] * DT_S)])
    z = 100.0 + np.concatenate([[0.0], np.cumsum(v[:-1] * DT_S + 0.5 * accel[:-1] * DT_S**2)])
    z_baro = z + rng.normal(0.0, 0.3, n)
    # row i carries the mean acceleration over the interval that ends at row i
    a_meas = np.concatenate([[0.0], accel[:-1]]) + 0.15 + rng.normal(0.0, 0.1, n)
    return t, z_baro, a_meas, v, t_step


def _delay_s(t: np.ndarray, climb: np.ndarray, t_step: float, threshold: float) -> float:
    crossed = np.nonzero((t >= t_step) & (climb >= threshold))[0]
    assert crossed.size, "never reached the threshold"
    return float(t[crossed[0]] - t_step)


def test_step_climb_is_detected_without_the_barometer_only_lag() -> None:
    # Delay until the climb estimate first reaches 1 m/s (half the step), minus the delay of
    # the true climb rate itself (0.275 s), averaged over 5 seeds. Measured: kf3 about 0.0 s,
    # barometer-only about 0.4 s.
    kf3_lag, baro_lag = [], []
    for seed in range(5):
        t, z_baro, a_meas, v_true, t_step = _step_climb(seed)
        truth = _delay_s(t, v_true, t_step, 1.0)
        kf3 = run_batch(z_baro, a_meas, DT_S, ESP32)
        kf3_lag.append(_delay_s(t, kf3.climb_m_s, t_step, 1.0) - truth)
        baro_lag.append(
            _delay_s(t, run_baro_batch(z_baro, DT_S, BARO_TUNED).climb_m_s, t_step, 1.0) - truth
        )
    assert abs(np.mean(kf3_lag)) < 0.1
    assert np.mean(baro_lag) > 0.3
