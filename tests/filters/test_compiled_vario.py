"""The compiled variometer loops (``fast`` extra) give what the Python loops give.

On conformance data set C (40 Hz paraglider flight) in every reference mode, and for the
barometer-only filter, with uneven step lengths, the compiled rows equal the pure-Python rows
(the reference) to 1e-12, on numba's JIT and on the AOT extension.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from imuhal_filters.vario.batch import run_baro_batch, run_batch

# every test runs on numba's JIT and on the AOT extension (each skipped where unavailable)
pytestmark = pytest.mark.usefixtures("compiled_backend")

DATA = Path(__file__).resolve().parent.parent / "data" / "filters"


def _flight() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    d = np.genfromtxt(DATA / "vario_C_first50s.csv", delimiter=",", names=True)
    dt = np.full(len(d), 0.025)
    dt[::7] = 0.031  # uneven steps: the per-row dt is honoured
    return d["z_baro_cm"] / 100.0, d["a_meas_cms2"] / 100.0, dt


def _close(a: np.ndarray, b: np.ndarray) -> None:
    assert np.allclose(a, b, rtol=1e-12, atol=1e-12)


@pytest.mark.parametrize("settings", [{}, {"mode": "avario"}, {"mode": "y2021"},
                                      {"accel_variance_m2_s4": 2.0, "initial_bias_m_s2": 0.1}],
                         ids=["esp32", "avario", "y2021", "tuned"])
def test_compiled_kf3_batch_equals_pure_python_on_data_set_c(
        settings: dict, monkeypatch: pytest.MonkeyPatch) -> None:
    z, a, dt = _flight()
    compiled = run_batch(z, a, dt, settings)
    monkeypatch.setenv("IMUHAL_NO_JIT", "1")
    ref = run_batch(z, a, dt, settings)
    _close(compiled.altitude_m, ref.altitude_m)
    _close(compiled.climb_m_s, ref.climb_m_s)
    _close(compiled.accel_bias_m_s2, ref.accel_bias_m_s2)  # type: ignore[arg-type]
    assert not np.array_equal(ref.climb_m_s, run_batch(z, a, 0.025, settings).climb_m_s)


def test_compiled_baro_batch_equals_pure_python_on_data_set_c(
        monkeypatch: pytest.MonkeyPatch) -> None:
    z, _, dt = _flight()
    compiled = run_baro_batch(z, dt)
    monkeypatch.setenv("IMUHAL_NO_JIT", "1")
    ref = run_baro_batch(z, dt)
    _close(compiled.altitude_m, ref.altitude_m)
    _close(compiled.climb_m_s, ref.climb_m_s)
