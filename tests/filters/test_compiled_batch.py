"""The compiled batch path (JIT and AOT kernels) gives what the pure-Python path gives.

Pure Python is the reference: on the conformance data (data set A), with every preset and
the corner cases the kernel handles itself (missing rows, values beyond the full scale, the
accelerometer gate), the compiled rows equal the Python rows to 1e-12, and the estimator
leaves with the same counters and turn bookkeeping, so batches chain either way.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest
from tests.filters.dataset_a import load_head

from imuhal_filters.common.batch import run_batch
from imuhal_filters.imufilter.estimator import ImuFilterEstimator
from imuhal_filters.madgwick.estimator import MadgwickEstimator
from imuhal_filters.mahony.estimator import MahonyEstimator

# every test runs on numba's JIT and on the AOT extension (each skipped where unavailable)
pytestmark = pytest.mark.usefixtures("compiled_backend")

CASES = [
    {},
    {"preset": "reference", "inv_sqrt": "exact"},
    {"preset": "seed"},
    {"use_mag": False},
    {"turn_compensation": False, "accel_soft_gate_g": None, "mag_reference": "xio_release"},
    {"nominal_airspeed_m_s": 10.0},  # turns compensated by the nominal airspeed
]


def _data() -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    t, gyro, accel, mag, _ = load_head()
    gyro, accel, mag = gyro.copy(), accel.copy(), mag.copy()
    mag[1::3] = np.nan            # a slower magnetometer
    accel[400:410] = np.nan       # an accelerometer gap
    gyro[500, 1] = 1e9            # an impossible gyro value: dropped, counted
    accel[600, 2] = np.inf        # an impossible accel value: dropped, counted
    accel[700] = (0.0, 0.0, -25.0)  # 2.5 g: the hard gate (seed preset) closes
    return gyro, accel, mag, np.diff(t, prepend=t[0] - 0.005)


def _both(settings: dict, monkeypatch: pytest.MonkeyPatch, mag: bool = True,
          cls: type = MadgwickEstimator) -> tuple[np.ndarray, np.ndarray, Any, Any]:
    gyro, accel, m, dt = _data()
    compiled = cls(cls.Settings(**settings))
    python = cls(cls.Settings(**settings))
    q_fast = run_batch(compiled, gyro, accel, m if mag else None, dt)
    monkeypatch.setenv("IMUHAL_NO_JIT", "1")
    q_ref = run_batch(python, gyro, accel, m if mag else None, dt)
    return q_fast, q_ref, compiled, python


@pytest.mark.parametrize("settings", CASES, ids=lambda s: ",".join(map(str, s.values())) or
                         "defaults")
def test_compiled_madgwick_batch_equals_pure_python_on_data_set_a(
        settings: dict, monkeypatch: pytest.MonkeyPatch) -> None:
    q_fast, q_ref, compiled, python = _both(settings, monkeypatch)
    assert np.array_equal(np.isnan(q_fast), np.isnan(q_ref))
    assert np.nanmax(np.abs(q_fast - q_ref)) <= 1e-12
    state, ref = compiled.get_state(), python.get_state()
    assert state["counters"] == ref["counters"]
    assert state["q"] == pytest.approx(ref["q"], abs=1e-12)
    turn, turn_ref = state["kinematics"].pop("turn"), ref["kinematics"].pop("turn")
    assert state["kinematics"] == ref["kinematics"]
    assert turn == pytest.approx(turn_ref, rel=1e-12)


MAHONY_CASES = [{}, {"preset": "seed"}, {"ki": 0.3, "use_mag": False},
                {"ki": 0.1, "turn_compensation": False, "accel_gate_g": (0.8, 1.2)}]


@pytest.mark.parametrize("settings", MAHONY_CASES,
                         ids=lambda s: ",".join(map(str, s.values())) or "defaults")
def test_compiled_mahony_batch_equals_pure_python_on_data_set_a(
        settings: dict, monkeypatch: pytest.MonkeyPatch) -> None:
    q_fast, q_ref, compiled, python = _both(settings, monkeypatch, cls=MahonyEstimator)
    assert np.array_equal(np.isnan(q_fast), np.isnan(q_ref))
    assert np.nanmax(np.abs(q_fast - q_ref)) <= 1e-12
    state, ref = compiled.get_state(), python.get_state()
    assert state["counters"] == ref["counters"]
    assert state["filter"]["integral"] == pytest.approx(ref["filter"]["integral"], abs=1e-12)


def test_compiled_6dof_batch_equals_pure_python(monkeypatch: pytest.MonkeyPatch) -> None:
    q_fast, q_ref, compiled, python = _both({}, monkeypatch, mag=False)
    assert np.nanmax(np.abs(q_fast - q_ref)) <= 1e-12
    assert compiled.get_state()["counters"] == python.get_state()["counters"]


def test_the_kernel_counts_what_the_python_path_counts(monkeypatch: pytest.MonkeyPatch) -> None:
    _, _, compiled, _ = _both({"preset": "seed"}, monkeypatch)
    counters = compiled.get_state()["counters"]
    assert counters["beyond_full_scale"] == {"gyro": 1, "accel": 1}
    assert counters["gate_closed_steps"] >= 1


def test_fast32_mode_stays_on_the_python_path(monkeypatch: pytest.MonkeyPatch) -> None:
    """The float32 square root of the reference mode has no kernel: same results anyway."""
    q_fast, q_ref, _, _ = _both({"preset": "reference"}, monkeypatch)
    assert np.array_equal(q_fast, q_ref, equal_nan=True)


IMUFILTER_CASES = [{}, {"velocity": False}, {"gain": 2.0, "sd_acc_g": 0.05},
                   {"turn_compensation": False, "dt_from_timestamps": False}]


@pytest.mark.parametrize("settings", IMUFILTER_CASES,
                         ids=lambda s: ",".join(map(str, s.values())) or "defaults")
def test_compiled_imufilter_batch_equals_pure_python_on_data_set_a(
        settings: dict, monkeypatch: pytest.MonkeyPatch) -> None:
    q_fast, q_ref, compiled, python = _both(settings, monkeypatch, cls=ImuFilterEstimator)
    assert np.array_equal(np.isnan(q_fast), np.isnan(q_ref))
    assert np.nanmax(np.abs(q_fast - q_ref)) <= 1e-12
    state, ref = compiled.get_state(), python.get_state()
    assert state["counters"] == ref["counters"]
    f, f_ref = state["filter"], ref["filter"]
    assert f["var"] == pytest.approx(f_ref["var"], rel=1e-12, abs=1e-15)
    assert f["gain"] == pytest.approx(f_ref["gain"], rel=1e-12)
    for key, value in f["velocity"].items():
        assert value == pytest.approx(f_ref["velocity"][key], rel=1e-12, abs=1e-12), key


def test_one_step_length_for_every_row_runs_compiled_like_python(
        monkeypatch: pytest.MonkeyPatch) -> None:
    """A scalar ``dt_s`` (broadcast, read-only) reaches the kernel as the array it takes."""
    gyro, accel, m, _ = _data()
    compiled = run_batch(MadgwickEstimator(), gyro, accel, m, 0.005)
    monkeypatch.setenv("IMUHAL_NO_JIT", "1")
    ref = run_batch(MadgwickEstimator(), gyro, accel, m, 0.005)
    assert np.nanmax(np.abs(compiled - ref)) <= 1e-12


def test_a_kernel_refuses_arguments_of_another_type_naming_them() -> None:
    """The extension reads memory as its signature says: anything else is refused first."""
    from imuhal_filters.vario.fast import baro_rows

    z = np.zeros(4)
    frozen = np.full(4, 0.1)
    frozen.flags.writeable = False
    good = (np.zeros(5), 1.0, 1.0, z, np.full(4, 0.1), np.zeros((4, 2)))
    baro_rows(*good)
    for i, bad, what in [(3, z.astype(np.float32), "float32"),
                         (5, np.zeros((2, 4)).T, "not in C order"),
                         (1, 1, "int"),
                         (4, frozen, "read-only")]:
        args = list(good)
        args[i] = bad
        with pytest.raises(TypeError, match=f"baro_rows: argument .* must be .*{what}"):
            baro_rows(*args)
