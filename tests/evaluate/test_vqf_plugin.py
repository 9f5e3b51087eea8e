"""The vqf plugin gives the package's own outputs on the same samples."""

from __future__ import annotations

import numpy as np
import pytest
from tests.support.broad_synthetic import RATE_HZ, synthetic_trial

from imuhal.core.conventions import ENU, NED, VectorKind, convert_quat, vector_to_ned
from imuhal_filters.common.batch import run_batch

vqf = pytest.importorskip("vqf")
from imuhal_filters.vqf.estimator import VqfEstimator  # noqa: E402 (needs the vqf package)

TRIAL = synthetic_trial(seconds=2.0, seed=3)
TS = 1.0 / RATE_HZ


def _ned(key: str, kind: VectorKind) -> np.ndarray:
    return vector_to_ned(TRIAL[key], ENU, kind)


@pytest.mark.parametrize("withhold", [{}, {"withhold_speed_m_s": 3.0},
                                      {"manoeuvre_speed_m_s": None}])
@pytest.mark.parametrize("use_mag", [True, False])
def test_outputs_equal_the_packages_own(use_mag, withhold):
    # slow hand-held motion: the input preprocessing (the manoeuvre detector by default, the
    # speed bound when asked for) withholds nothing
    est = VqfEstimator({"sample_period_s": TS, "use_mag": use_mag, **withhold})
    q = run_batch(est, _ned("imu_gyr", VectorKind.ANGULAR_RATE),
                  _ned("imu_acc", VectorKind.SPECIFIC_FORCE),
                  _ned("imu_mag", VectorKind.MAGNETIC_FIELD))
    ref = vqf.VQF(TS).updateBatch(TRIAL["imu_gyr"], TRIAL["imu_acc"],
                                  TRIAL["imu_mag"] if use_mag else None)
    expected = convert_quat(ref["quat9D" if use_mag else "quat6D"], ENU, NED)
    np.testing.assert_allclose(q, expected, atol=1e-9)


def test_offline_mode_equals_the_packages_offline_variant():
    est = VqfEstimator({"sample_period_s": TS, "offline": True})
    q = est.smooth(_ned("imu_gyr", VectorKind.ANGULAR_RATE),
                   _ned("imu_acc", VectorKind.SPECIFIC_FORCE),
                   _ned("imu_mag", VectorKind.MAGNETIC_FIELD))
    ref = vqf.offlineVQF(TRIAL["imu_gyr"], TRIAL["imu_acc"], TRIAL["imu_mag"], TS, None)
    np.testing.assert_allclose(q, convert_quat(ref["quat9D"], ENU, NED), atol=1e-12)


def test_rest_is_reported_on_the_estimates():
    from imuhal.core.samples import AccelSample, Frame, GyroSample

    est = VqfEstimator({"sample_period_s": 0.01})
    out = []
    for i in range(400):  # 4 s still and level
        t = i * 10_000_000
        est.process(AccelSample(t_ns=t, device="d", frame=Frame.BODY_NED,
                                accel_m_s2=(0.0, 0.0, -9.81)))
        out += est.process(GyroSample(t_ns=t, device="d", frame=Frame.BODY_NED,
                                      gyro_rad_s=(0.0, 0.0, 0.0)))
    assert not out[0].diagnostics["rest_detected"]
    assert out[-1].diagnostics["rest_detected"]
    assert out[-1].diagnostics["mag_disturbed"] is None  # no magnetometer: not applicable


def test_offline_mode_refuses_to_run_live():
    est = VqfEstimator({"offline": True})
    with pytest.raises(ValueError, match="offline"):
        est.update((0.0, 0.0, 0.0), (0.0, 0.0, -9.81))


def test_estimate_runs_the_offline_mode_over_a_whole_csv(tmp_path):
    from imuhal.cli.main import main

    n = 300
    g = _ned("imu_gyr", VectorKind.ANGULAR_RATE)[:n]
    a = _ned("imu_acc", VectorKind.SPECIFIC_FORCE)[:n]
    m = _ned("imu_mag", VectorKind.MAGNETIC_FIELD)[:n]
    rows = np.column_stack([np.arange(n) * TS, g, a, m])
    src = tmp_path / "in.csv"
    src.write_text("t_s,gx_rad_s,gy_rad_s,gz_rad_s,ax_m_s2,ay_m_s2,az_m_s2,mx_ut,my_ut,mz_ut\n"
                   + "\n".join(",".join(repr(float(v)) for v in r) for r in rows) + "\n")
    out = tmp_path / "out.csv"
    assert main(["estimate", "vqf", str(src), "-o", str(out), "--set", "offline=true",
                 "--set", f"sample_period_s={TS!r}"]) == 0
    got = np.loadtxt(out, delimiter=",", skiprows=1, usecols=(1, 2, 3, 4))
    ref = vqf.offlineVQF(TRIAL["imu_gyr"][:n], TRIAL["imu_acc"][:n], TRIAL["imu_mag"][:n], TS,
                         None)
    np.testing.assert_allclose(got, convert_quat(ref["quat9D"], ENU, NED), atol=1e-9)


def _turn_tilt_deg(settings: dict) -> tuple[np.ndarray, VqfEstimator]:
    from tests.filters.decoupled_flight_motion import flight
    from tests.filters.decoupled_motion import tilt_error_deg

    f = flight(40.0, turn_deg_s=30.0)  # 47 deg of bank at 20 m/s, no speed source
    est = VqfEstimator({"sample_period_s": f.dt_s, "use_mag": False, **settings})
    q = run_batch(est, f.gyro_rad_s, f.accel_m_s2, None)
    return tilt_error_deg(q, f.q_true)[f.t_s >= 20.0], est


@pytest.mark.parametrize("settings", [{}, {"manoeuvre_speed_m_s": None,
                                            "withhold_speed_m_s": 3.0}])
def test_a_sustained_turn_is_withheld_from_vqf_and_without_preprocessing_it_is_the_package(
        settings: dict) -> None:
    tilt, est = _turn_tilt_deg(settings)
    faithful, plain = _turn_tilt_deg({"manoeuvre_speed_m_s": None})
    assert plain.diagnostics()["accel_withheld"] == 0
    assert faithful.mean() > 20.0  # the package's filter follows the apparent vertical
    # measured 33.7 faithful; the manoeuvre detector (default) 11.9, speed 3 m/s 4.0
    assert tilt.mean() < 0.5 * faithful.mean()
    assert est.diagnostics()["accel_withheld"] > 0
