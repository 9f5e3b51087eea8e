"""The compiled per-sample steps (JIT and AOT kernels) give what the Python step gives.

Madgwick, Mahony and imuFilter.

``process()`` runs each gyro sample's filter step in the compiled per-sample kernel when one
is selected (the AOT extension in ``auto`` mode; either backend when ``IMUHAL_KERNELS``
forces it). Pure Python is the reference: on conformance data set A, sample by sample,
with every preset and the corner cases (a slower magnetometer, an accelerometer gap, values
beyond the full scale, the hard gate closing), the quaternions, the gravity-compensated
acceleration and every diagnostic equal the Python step's to 1e-12, and the estimator leaves
with the same counters.
"""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

import numpy as np
import pytest
from tests.filters.dataset_a import load_head

from imuhal.core.samples import (
    AccelSample,
    Frame,
    GyroSample,
    MagSample,
    Sample,
    VelocitySample,
)
from imuhal.estimation.outputs import AttitudeEstimate
from imuhal_filters.imufilter.estimator import ImuFilterEstimator
from imuhal_filters.madgwick.estimator import MadgwickEstimator
from imuhal_filters.mahony.estimator import MahonyEstimator

# every test runs on numba's JIT and on the AOT extension (each skipped where unavailable)
pytestmark = pytest.mark.usefixtures("compiled_backend")

CASES = [
    (MadgwickEstimator, {}),
    (MadgwickEstimator, {"preset": "reference", "inv_sqrt": "exact"}),
    (MadgwickEstimator, {"preset": "seed"}),
    (MadgwickEstimator, {"use_mag": False}),
    (MadgwickEstimator, {"turn_compensation": False, "accel_soft_gate_g": None,
                         "mag_reference": "xio_release"}),
    (MadgwickEstimator, {"nominal_airspeed_m_s": 10.0}),
    (MahonyEstimator, {}),
    (MahonyEstimator, {"preset": "seed"}),
    (MahonyEstimator, {"ki": 0.2, "use_mag": False}),
    (MahonyEstimator, {"ki": 0.1, "accel_soft_gate_g": None, "nominal_airspeed_m_s": 10.0}),
    (ImuFilterEstimator, {}),
    (ImuFilterEstimator, {"velocity": False, "gain": 2.0}),
    (ImuFilterEstimator, {"preset": "seed", "sd_acc_g": 0.05}),
]


def _samples(velocity_from: int | None = None) -> Iterator[Sample]:
    """Data set A's head with the corner cases; from row ``velocity_from`` on, a 12 m/s
    ground velocity every 20th row (a speed source arriving mid-stream)."""
    t, gyro, accel, mag, _ = load_head()
    accel = accel.copy()
    accel[700] = (0.0, 0.0, -25.0)  # 2.5 g: the hard gate (seed preset) closes
    accel[600, 2] = 1e9             # beyond the full scale: dropped, counted
    for i, t_s in enumerate(t):
        t_ns = round(t_s * 1e9)
        if not 400 <= i < 410:      # an accelerometer gap
            yield AccelSample(t_ns=t_ns, device="imu", frame=Frame.BODY_NED,
                              accel_m_s2=tuple(accel[i]))
        if i % 3 == 0:              # a slower magnetometer
            yield MagSample(t_ns=t_ns, device="mag", frame=Frame.BODY_NED,
                            mag_ut=tuple(mag[i]))
        if velocity_from is not None and i >= velocity_from and i % 20 == 0:
            yield VelocitySample(t_ns=t_ns, device="gnss", velocity_ned_m_s=(12.0, 1.0, 0.0))
        yield GyroSample(t_ns=t_ns, device="imu", frame=Frame.BODY_NED,
                         gyro_rad_s=tuple(gyro[i]))


def _run(cls: type, settings: dict, velocity_from: int | None = None
         ) -> tuple[list[AttitudeEstimate], dict[str, Any]]:
    est = cls(cls.Settings(**settings))
    out = [e for s in _samples(velocity_from) for e in est.process(s)]
    return out, est.diagnostics()  # type: ignore[return-value]


def _case_id(case: Any) -> str:
    return case.name if isinstance(case, type) else ",".join(map(str, case.values())) or "defaults"


@pytest.mark.parametrize(("cls", "settings"), CASES, ids=_case_id)
def test_compiled_step_equals_python_step_on_data_set_a(
        cls: type, settings: dict, monkeypatch: pytest.MonkeyPatch) -> None:
    assert cls(cls.Settings(**settings))._sample_kernel is not None
    fast, fast_counts = _run(cls, settings)
    monkeypatch.setenv("IMUHAL_KERNELS", "python")
    assert cls(cls.Settings(**settings))._sample_kernel is None
    ref, ref_counts = _run(cls, settings)
    assert len(fast) == len(ref) > 1000
    assert np.allclose([e.q_body_to_ned for e in fast], [e.q_body_to_ned for e in ref],
                       rtol=0, atol=1e-12)
    assert np.allclose([e.linear_accel_ned_m_s2 for e in fast if e.linear_accel_ned_m_s2],
                       [e.linear_accel_ned_m_s2 for e in ref if e.linear_accel_ned_m_s2],
                       rtol=0, atol=1e-12)
    for f, r in zip(fast, ref, strict=True):
        assert list(f.diagnostics) == list(r.diagnostics)  # the same columns, in order
        for key, value in r.diagnostics.items():
            if isinstance(value, (bool, str)):
                assert f.diagnostics[key] == value, key
            else:
                assert np.allclose(f.diagnostics[key], value, rtol=0, atol=1e-12), key
    assert fast_counts == ref_counts
    assert fast_counts["beyond_full_scale"]["accel"] == 1
    assert fast_counts["steps"] > 1000


def test_fast32_square_root_keeps_the_python_step() -> None:
    # the kernel implements the exact 1/sqrt only: the release's fast32 stays in Python
    est = MadgwickEstimator(MadgwickEstimator.Settings(preset="reference"))
    assert est._sample_kernel is None


@pytest.mark.parametrize("cls", [MadgwickEstimator, MahonyEstimator], ids=lambda c: c.name)
def test_a_velocity_source_arriving_mid_stream_compensates_as_the_python_step_does(
        cls: type, monkeypatch: pytest.MonkeyPatch) -> None:
    # the compiled path skips the turn compensation only while no speed source has come
    fast, fast_counts = _run(cls, {}, velocity_from=800)
    monkeypatch.setenv("IMUHAL_KERNELS", "python")
    ref, ref_counts = _run(cls, {}, velocity_from=800)
    assert [e.diagnostics["turn_compensation"] for e in fast] == \
        [e.diagnostics["turn_compensation"] for e in ref]
    assert {e.diagnostics["turn_compensation"] for e in fast} == {"none", "velocity"}
    assert np.allclose([e.q_body_to_ned for e in fast], [e.q_body_to_ned for e in ref],
                       rtol=0, atol=1e-12)
    assert fast_counts == ref_counts
