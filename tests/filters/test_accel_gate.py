"""The accelerometer gates every AHRS shares (common/gate.py on common/fast_ahrs.py).

The hard gate trusts a reading strictly inside (lower, upper) g; the soft gate weights the
correction by 1 / (1 + ((|a| - 1) / width)^2). The functions are the ones the compiled
kernels are built from, called here as Python (the compiled side is compared with the Python
filters by test_compiled_batch.py and test_compiled_sample.py).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from imuhal_filters.common.fast_ahrs import accel_gate_kernel, soft_gate_distrust
from imuhal_filters.common.gate import AccelGate, soft_gate_weight


@pytest.mark.parametrize(("z_g", "expected"), [(0.6, False), (0.6000001, True), (1.0, True),
                                               (1.3999999, True), (1.4, False), (2.5, False)])
def test_the_hard_gate_is_open_strictly_inside_its_bounds(z_g: float, expected: bool) -> None:
    assert AccelGate(0.6, 1.4).is_open((0.0, 0.0, z_g)) is expected


def test_without_a_reading_the_gate_is_closed_and_the_correction_unweighted() -> None:
    assert AccelGate(0.6, 1.4).gates(None, 0.05) == (False, 1.0)


@pytest.mark.parametrize(("norm_g", "width_g", "weight"), [
    (1.0, 0.05, 1.0), (1.05, 0.05, 0.5), (0.9, 0.05, 0.2), (3.0, None, 1.0)])
def test_the_soft_gate_weight_halves_one_width_from_1_g(
        norm_g: float, width_g: float | None, weight: float) -> None:
    assert soft_gate_weight((0.0, norm_g, 0.0), width_g) == pytest.approx(weight, rel=1e-12)


def test_both_gates_from_one_magnitude_equal_the_separate_gates() -> None:
    gate = AccelGate(0.7, 1.3)
    rng = np.random.default_rng(29)
    for a in rng.normal(0.0, 0.8, (500, 3)):
        reading = (float(a[0]), float(a[1]), float(a[2]))
        assert gate.gates(reading, 0.05) == (gate.is_open(reading),
                                             soft_gate_weight(reading, 0.05))


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
    open_, weight = accel_gate_kernel(True, 0.0, 0.0, 1.2, 0.6, 1.4, 0.1)
    assert open_ is True
    assert weight == pytest.approx(0.2, rel=1e-12)
