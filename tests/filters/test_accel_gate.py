"""The accelerometer gates every AHRS shares (common/gate.py on common/fast_ahrs.py).

The hard gate trusts a reading strictly inside (lower, upper) g; the complementary filters'
soft gate weights the correction by 1 / (1 + (u / width)^2), u the unmodelled acceleration
(the reading minus the gravity the attitude predicts); ``soft_gate_weight`` (the decoupled
filter's) and the Freescale filter's distrust look at ((|a| - 1) / width) alone. The
functions are the ones the compiled kernels are built from, called here as Python (the
compiled side is compared with the Python filters by test_compiled_batch.py and
test_compiled_sample.py).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from imuhal_filters.common.fast_ahrs import (
    accel_gate_kernel,
    soft_gate_distrust,
    unmodelled_accel_g,
)
from imuhal_filters.common.gate import AccelGate, soft_gate_weight
from imuhal_filters.common.quat import IDENTITY

PITCHED_10_DEG = (math.cos(math.radians(5.0)), 0.0, math.sin(math.radians(5.0)), 0.0)
"""Body -> NED, nose 10 deg up: gravity reads (-sin 10 deg, 0, cos 10 deg) g, gravity
positive."""


@pytest.mark.parametrize(("z_g", "expected"), [(0.6, False), (0.6000001, True), (1.0, True),
                                               (1.3999999, True), (1.4, False), (2.5, False)])
def test_the_hard_gate_is_open_strictly_inside_its_bounds(z_g: float, expected: bool) -> None:
    assert AccelGate(0.6, 1.4).is_open((0.0, 0.0, z_g)) is expected


def test_without_a_reading_the_gate_is_closed_and_the_correction_unweighted() -> None:
    assert AccelGate(0.6, 1.4).gates(None, 0.05, IDENTITY) == (False, 1.0)


def test_the_unmodelled_acceleration_is_the_reading_minus_the_predicted_gravity() -> None:
    pitch = math.radians(10.0)
    gravity = (-math.sin(pitch), 0.0, math.cos(pitch))
    assert unmodelled_accel_g(*gravity, *PITCHED_10_DEG) == pytest.approx(0.0, abs=1e-15)
    pushed = (gravity[0] + 0.3, gravity[1], gravity[2])
    assert unmodelled_accel_g(*pushed, *PITCHED_10_DEG) == pytest.approx(0.3, rel=1e-12)


def test_a_forward_push_closes_the_soft_gate_that_its_magnitude_leaves_open() -> None:
    """0.25 g forward on a level board: |a| is 1.03 g (the magnitude's weight 0.73), the
    vector is 0.25 g off gravity (weight 0.04): the launch's run-up (issue 27)."""
    pushed = (0.25, 0.0, 1.0)
    _, weight = AccelGate(0.0, math.inf).gates(pushed, 0.05, IDENTITY)
    assert soft_gate_weight(pushed, 0.05) > 0.7
    assert weight == pytest.approx(1.0 / (1.0 + 5.0 ** 2), rel=1e-12)


def test_the_soft_gate_weight_halves_one_width_off_the_predicted_gravity() -> None:
    pitch = math.radians(10.0)
    reading = (-math.sin(pitch), 0.05, math.cos(pitch))
    assert AccelGate(0.0, math.inf).gates(reading, 0.05, PITCHED_10_DEG)[1] == \
        pytest.approx(0.5, rel=1e-12)


@pytest.mark.parametrize(("norm_g", "width_g", "weight"), [
    (1.0, 0.05, 1.0), (1.05, 0.05, 0.5), (0.9, 0.05, 0.2), (3.0, None, 1.0)])
def test_the_magnitude_weight_halves_one_width_from_1_g(
        norm_g: float, width_g: float | None, weight: float) -> None:
    assert soft_gate_weight((0.0, norm_g, 0.0), width_g) == pytest.approx(weight, rel=1e-12)


def test_at_the_attitude_of_the_reading_the_soft_gate_is_the_magnitude_weight() -> None:
    """A reading along the gravity the attitude predicts: all its unmodelled acceleration is
    in its magnitude, so both weights agree (and the hard gate is the magnitude's)."""
    gate = AccelGate(0.7, 1.3)
    rng = np.random.default_rng(29)
    for a in rng.normal(0.0, 0.8, (500, 3)):
        reading = (float(a[0]), float(a[1]), float(a[2]))
        n = math.sqrt(sum(v * v for v in reading))
        # the body -> NED quaternion whose gravity (0, 0, 1) in the body reads along a
        axis = (reading[1] / n, -reading[0] / n, 0.0)
        half = 0.5 * math.acos(max(-1.0, min(1.0, reading[2] / n)))
        s = math.sin(half) / max(math.hypot(axis[0], axis[1]), 1e-300)
        q = (math.cos(half), axis[0] * s, axis[1] * s, 0.0)
        open_, weight = gate.gates(reading, 0.05, q)  # type: ignore[arg-type]
        assert open_ is gate.is_open(reading)
        assert weight == pytest.approx(soft_gate_weight(reading, 0.05), rel=1e-9, abs=1e-12)


def test_the_freescale_distrust_is_the_inverse_weight() -> None:
    """The Kalman filter multiplies its accelerometer noise by the square of what the
    complementary filters divide their correction by."""
    norm = math.sqrt(0.3 ** 2 + 1.1 ** 2)
    assert soft_gate_distrust(norm, 0.02) == pytest.approx(
        1.0 / soft_gate_weight((0.3, 1.1, 0.0), 0.02), rel=1e-12)
    assert soft_gate_distrust(norm, 0.0) == 1.0  # no soft gate


def test_a_helper_kernel_called_from_python_runs_as_python(
        monkeypatch: pytest.MonkeyPatch) -> None:
    """Its compiled form exists only inside the kernels that call it: no backend needed."""
    monkeypatch.setenv("IMUHAL_KERNELS", "python")
    open_, weight = accel_gate_kernel(True, 0.0, 0.0, 1.2, *IDENTITY, 0.6, 1.4, 0.1)
    assert open_ is True
    assert weight == pytest.approx(0.2, rel=1e-12)
