"""The manoeuvre detector (imuhal_filters/common/innovation.py): what a hand cannot do.

Fed the innovation directly (reading minus the filter's gravity, almost-inertial frame, g):
the filter's gravity is held at straight down, so each reading is gravity plus the
acceleration under test. Seeded, synthetic, 200 Hz.
"""

from __future__ import annotations

import math

import numpy as np

from imuhal_filters.common.innovation import (
    GAP_VELOCITY_KEPT,
    ManoeuvreDetector,
    ManoeuvreParams,
)

DT_S = 0.005
G = 9.80665
DOWN = (0.0, 0.0, 1.0)


def _weights(acc_m_s2: np.ndarray) -> np.ndarray:
    """The detector's weight for each row of kinematic acceleration (m/s^2)."""
    det = ManoeuvreDetector(ManoeuvreParams())
    return np.array([det.weight((a[0] / G, a[1] / G, 1.0 + a[2] / G), DOWN, DT_S)
                     for a in acc_m_s2])


def _t(duration_s: float) -> np.ndarray:
    return np.arange(0.0, duration_s, DT_S)


def test_hand_strokes_keep_full_weight() -> None:
    # a hand moving the board back and forth 0.3 m at 1 Hz (peak speed 1.9 m/s, 1.2 g),
    # with scatter: the velocity reverses every half second
    t = _t(20.0)
    rng = np.random.default_rng(1)
    x = 0.3 * (2 * math.pi) ** 2 * np.sin(2 * math.pi * t)
    acc = np.stack([x, 0.5 * x, np.zeros_like(t)], axis=1) + rng.normal(0, 1.0, (t.size, 3))
    # (the first quarter stroke from rest is a steady push until the scatter builds up)
    assert _weights(acc)[int(1.0 / DT_S):].min() > 0.95


def test_a_take_off_push_is_gated_within_a_second() -> None:
    # 0.5 g forward for 4 s (rc-flight's take-off run): a speed of 20 m/s no hand reaches
    t = _t(4.0)
    acc = np.zeros((t.size, 3))
    acc[:, 0] = 0.5 * G
    w = _weights(acc)
    assert w[int(1.0 / DT_S):].max() < 0.01


def test_a_banked_turn_is_gated() -> None:
    # a coordinated turn without a speed source: 5 m/s^2 turning with the heading at
    # 0.5 rad/s (20 m/s x 0.25 rad/s... as the board sees it in the inertial frame)
    t = _t(8.0)
    acc = 5.0 * np.stack([np.cos(0.5 * t), np.sin(0.5 * t), np.zeros_like(t)], axis=1)
    assert _weights(acc)[int(1.5 / DT_S):].max() < 0.05


def test_a_steady_tilt_error_is_corrected_again() -> None:
    # a 5 deg tilt error is a steady innovation of 0.85 m/s^2 across gravity: below the
    # 1 m/s^2 floor it never counts as a manoeuvre, and its velocity (leaky) stays small
    t = _t(60.0)
    acc = np.zeros((t.size, 3))
    acc[:, 0] = G * math.sin(math.radians(5.0))
    assert _weights(acc).min() > 0.5


def test_a_large_steady_tilt_error_is_taken_as_one_within_a_minute() -> None:
    # 12 deg (2 m/s^2 steady): first a manoeuvre, then the drift mean takes it out
    t = _t(90.0)
    acc = np.zeros((t.size, 3))
    acc[:, 0] = G * math.sin(math.radians(12.0))
    w = _weights(acc)
    assert w[int(2.0 / DT_S)] < 0.1
    assert w[int(60.0 / DT_S):].min() > 0.85  # its leaky velocity, 6 m/s, alone


def test_rest_resets_the_velocity() -> None:
    det = ManoeuvreDetector(ManoeuvreParams())
    for _ in range(int(2.0 / DT_S)):
        det.weight((0.5, 0.0, 1.0), DOWN, DT_S)
    assert det.weight((0.5, 0.0, 1.0), DOWN, DT_S) < 0.01
    det.reset()
    assert det.weight((0.0, 0.0, 1.0), DOWN, DT_S) > 0.99


def test_a_restart_after_a_gap_keeps_half_the_velocity_and_drops_the_window() -> None:
    # a clip mid-manoeuvre: the velocity change before it is evidence still, the 0.5 s
    # window's readings are gone
    det = ManoeuvreDetector(ManoeuvreParams())
    for _ in range(int(2.0 / DT_S)):
        det.weight((0.5, 0.0, 1.0), DOWN, DT_S)
    v_before = list(det.v_m_s)
    det.restart()
    assert det.v_m_s == [GAP_VELOCITY_KEPT * v for v in v_before]
    assert (det.mean_m_s2, det.mean_sq_m2_s4) == ([0.0, 0.0, 0.0], 0.0)
