"""The decoupled estimator's look-back (imuhal_filters/decoupled/lookback.py): what the
manoeuvre detector closed on is filtered again in full when its velocity change comes back
(a hand's stroke), and stays withheld when it does not (a vehicle's push).

The look-back is fed directly (readings and innovations along x, one filter step at a time,
200 Hz); the estimator, a level board moved by hand (strokes from rest, back-and-forth
strokes; seeded).
"""

from __future__ import annotations

import math

import numpy as np

from imuhal_filters.decoupled.butterworth import ButterworthLowPass
from imuhal_filters.decoupled.estimator import DecoupledEstimator
from imuhal_filters.decoupled.lookback import LookBack

DT_S = 0.005
G = 9.80665
TAU_S = 3.0
SPEED_M_S = 8.0
EPISODE_MAX_S = 3.0


def _feed(steps: list[tuple[float, float]], rest_from: int | None = None
          ) -> tuple[LookBack, ButterworthLowPass, ButterworthLowPass]:
    """Feed (horizontal acceleration m/s^2, detector weight) steps to a look-back and its
    filter; returns them and a filter that took every step in full."""
    lb = LookBack(TAU_S, 0.5, EPISODE_MAX_S, SPEED_M_S, 0.5)
    filt, full = ButterworthLowPass(TAU_S), ButterworthLowPass(TAU_S)
    for i, (acc, w) in enumerate(steps):
        a = (acc / G, 0.0, 1.0)
        weight, _ = lb.step(filt, a, DT_S, w, 1.0, (acc, 0.0, 0.0),
                            rest_from is not None and i >= rest_from)
        filt.step(a, DT_S * weight)
        full.step(a, DT_S)
    return lb, filt, full


def _steps(seconds: float, acc: float, w: float) -> list[tuple[float, float]]:
    return [(acc, w)] * round(seconds / DT_S)


def test_a_closed_stretch_whose_velocity_comes_back_is_filtered_again_in_full() -> None:
    # a stroke: 1 s still, 0.4 s pushed at 2 m/s^2 (the detector closes after 0.2 s of it),
    # then braked at -2 m/s^2 for 0.4 s with the detector open again: the velocity is back
    steps = (_steps(1.0, 0.0, 1.0) + _steps(0.2, 2.0, 1.0) + _steps(0.2, 2.0, 0.0)
             + _steps(0.4, -2.0, 1.0) + _steps(0.5, 0.0, 1.0))
    lb, filt, full = _feed(steps)
    assert lb.readmitted == 1
    assert filt.state == full.state


def test_a_push_whose_velocity_stays_is_kept_withheld_and_the_episode_ends() -> None:
    # 1 s still, then 2 m/s^2 on (4 m/s after 2 s: within the speed bound, never back)
    steps = _steps(1.0, 0.0, 1.0) + _steps(0.2, 2.0, 1.0) + _steps(EPISODE_MAX_S, 2.0, 0.0)
    lb, filt, full = _feed(steps)
    assert lb.readmitted == 0
    assert lb.episode_s is None  # over after EPISODE_MAX_S: only the look-back is kept
    assert lb.kept_s <= 0.5 + DT_S
    assert filt.state is not None and full.state is not None
    # the pushed readings stayed out: the filter is still level, the full one is not
    assert abs(filt.state[0]) < 0.25 * abs(full.state[0])


def test_beyond_the_speed_bound_a_closed_stretch_stays_withheld_even_if_it_comes_back(
        ) -> None:
    # 5 m/s^2 for 2 s (10 m/s: no hand), then braked back to the start's velocity
    steps = (_steps(1.0, 0.0, 1.0) + _steps(0.2, 5.0, 1.0) + _steps(1.8, 5.0, 0.0)
             + _steps(2.0, -5.0, 1.0))
    lb, filt, full = _feed(steps)
    assert lb.readmitted == 0
    assert filt.state != full.state


def test_coming_to_rest_ends_an_episode_as_a_stroke() -> None:
    # pushed and stopped short of braking fully: the rest detector says the board is still
    steps = (_steps(1.0, 0.0, 1.0) + _steps(0.2, 2.0, 1.0) + _steps(0.2, 2.0, 0.0)
             + _steps(0.3, -2.0, 1.0) + _steps(1.0, 0.0, 1.0))
    lb, filt, full = _feed(steps, rest_from=len(steps) - round(0.5 / DT_S))
    assert lb.readmitted == 1
    assert filt.state == full.state


def _strokes_from_rest(seconds: float, seed: int = 4) -> tuple[np.ndarray, np.ndarray]:
    """A level board held still and moved by hand along x, one stroke every 4 s: a push
    and a brake of 0.75 s each (1.5 m/s^2 peak, 0.4 m), with the hand's tremor (0.3 m/s^2
    RMS); the push is steady for its first half second (the steadiness statistic closes on
    it). Gyro and accelerometer rows (body NED, rad/s and m/s^2) with white noise."""
    rng = np.random.default_rng(seed)
    t = np.arange(round(seconds / DT_S)) * DT_S
    phase = np.mod(t, 4.0) - 1.0
    stroke = (phase >= 0.0) & (phase < 1.5)
    ax = np.where(stroke, 2.5 * np.sin(2 * math.pi * phase / 1.5), 0.0)
    ax += np.where(stroke, rng.normal(0.0, 0.3, t.size), 0.0)
    acc = np.stack([ax, np.zeros_like(t), np.full_like(t, -G)], axis=1)
    acc += rng.normal(0.0, 0.02, acc.shape)
    gyro = rng.normal(0.0, 0.002, acc.shape)
    return gyro, acc


def _tilt_rms_deg(settings: dict[str, object], gyro: np.ndarray, acc: np.ndarray
                  ) -> tuple[float, DecoupledEstimator]:
    est = DecoupledEstimator({"sample_period_s": DT_S, "use_mag": False, **settings})
    q = np.array([est.update(g, a, None, DT_S) for g, a in zip(gyro, acc, strict=True)])
    # the tilt from level: the NED down axis seen in the body against straight down
    down_z = 1.0 - 2.0 * (q[:, 1] ** 2 + q[:, 2] ** 2)
    tilt = np.degrees(np.arccos(np.clip(down_z, -1.0, 1.0)))
    return float(np.sqrt(np.mean(tilt ** 2))), est


def test_hand_strokes_from_rest_cost_the_defaults_nothing_against_the_handheld_preset() -> None:
    gyro, acc = _strokes_from_rest(40.0)
    defaults, est = _tilt_rms_deg({}, gyro, acc)
    handheld, _ = _tilt_rms_deg({"preset": "handheld"}, gyro, acc)
    assert est.get_state()["filter"]["lookback"]["readmitted"] > 0  # the detector closed
    assert defaults < 1.05 * handheld


def test_state_round_trips_within_an_episode_and_continues_identically() -> None:
    gyro, acc = _strokes_from_rest(12.0)
    a = DecoupledEstimator({"sample_period_s": DT_S, "use_mag": False})
    for g, f in zip(gyro, acc, strict=True):
        a.update(g, f, None, DT_S)
        if a.get_state()["filter"]["lookback"]["episode_s"] is not None:
            break
    else:
        raise AssertionError("no episode began")
    b = DecoupledEstimator({"sample_period_s": DT_S, "use_mag": False})
    b.set_state(a.get_state())
    n = len(gyro) // 2
    qa = [a.update(g, f, None, DT_S) for g, f in zip(gyro[n:], acc[n:], strict=True)]
    qb = [b.update(g, f, None, DT_S) for g, f in zip(gyro[n:], acc[n:], strict=True)]
    assert np.array_equal(qa, qb)


def test_hand_motion_the_detector_does_not_close_on_is_filtered_as_without_it() -> None:
    # a level board moved back and forth 0.3 m at 1 Hz with the hand's scatter (1 m/s^2),
    # started gently (the amplitude ramps up over 2 s): the detector's weight dips near its
    # bounds but never below one half, so every reading counts in full, exactly as with
    # VQF's settings alone
    rng = np.random.default_rng(2)
    t = np.arange(round(30.0 / DT_S)) * DT_S
    x = 0.3 * (2 * math.pi) ** 2 * np.sin(2 * math.pi * t) * np.clip(t / 2.0, 0.0, 1.0)
    acc = np.stack([x, 0.5 * x, np.full_like(t, -G)], axis=1) + rng.normal(0.0, 1.0, (t.size, 3))
    gyro = rng.normal(0.0, 0.002, acc.shape)

    def attitudes(settings: dict[str, object]) -> np.ndarray:
        est = DecoupledEstimator({"sample_period_s": DT_S, "use_mag": False, **settings})
        return np.array([est.update(g, a, None, DT_S) for g, a in zip(gyro, acc, strict=True)])

    assert np.array_equal(attitudes({}), attitudes({"preset": "handheld"}))
