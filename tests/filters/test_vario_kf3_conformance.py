"""vario-kf3 reproduces the seed author's three public implementations row by row.

Data set C (40 Hz paraglider flight): inputs rows 0..1999 in vario_C_first50s.csv; reference
outputs (float32 C, rows 0..399 and 1600..1999) in vario_kf3_<ref>_C_slices.csv. The filter is
run from row 0, as the references were. Tolerances from the conformance README for a float64
port: altitude 0.1 cm, climb rate 0.5 cm/s (bias: 0.5 cm/s^2, ours).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from imuhal_filters.vario.batch import run_batch
from imuhal_filters.vario.kf3 import Kalman3, Kf3Mode

DATA = Path(__file__).resolve().parent.parent / "data" / "filters"
DT_S = 0.025
ALT_TOL_CM, CLIMB_TOL_CMS, BIAS_TOL_CMS2 = 0.1, 0.5, 0.5

# mode -> (reference file tag, configure(zMeasVariance, zAccelVariance, zAccelBiasVariance))
REFERENCE_RUNS = {
    Kf3Mode.ESP32: ("esp32", (300.0, 50_000.0, 1.0)),
    Kf3Mode.AVARIO: ("avario", (200.0, 100.0, 1.0)),
    Kf3Mode.Y2021: ("2021", (200.0, 100_000.0, 0.005)),
}


def _inputs() -> np.ndarray:
    return np.genfromtxt(DATA / "vario_C_first50s.csv", delimiter=",", names=True)


def _reference(tag: str) -> np.ndarray:
    return np.genfromtxt(DATA / f"vario_kf3_{tag}_C_slices.csv", delimiter=",", names=True)


def _run_core(mode: Kf3Mode, variances: tuple[float, float, float], explicit_calls: bool
              ) -> np.ndarray:
    d = _inputs()
    kf = Kalman3(mode)
    kf.configure(*variances, z0=float(d["z_baro_cm"][0]), v0=0.0, bias0=0.0)
    out = np.empty((len(d), 3))
    for i, (z, a) in enumerate(zip(d["z_baro_cm"], d["a_meas_cms2"], strict=True)):
        if explicit_calls:  # the 2021 reference calls predict then update
            kf.predict(float(a), DT_S)
            kf.update(float(z))
        else:  # the firmware references make one update(z, a, dt) call
            kf.step(float(z), float(a), DT_S)
        out[i] = kf.x
    return out


@pytest.mark.parametrize("mode", list(REFERENCE_RUNS))
def test_core_matches_reference_at_every_row_of_both_windows(mode: Kf3Mode) -> None:
    tag, variances = REFERENCE_RUNS[mode]
    ref = _reference(tag)
    ours = _run_core(mode, variances, explicit_calls=mode is Kf3Mode.Y2021)
    rows = ref["idx"].astype(int)
    assert rows[0] == 0 and rows[-1] == 1999 and len(rows) == 800
    np.testing.assert_allclose(ours[rows, 0], ref["z_cm"], rtol=0, atol=ALT_TOL_CM)
    np.testing.assert_allclose(ours[rows, 1], ref["v_cms"], rtol=0, atol=CLIMB_TOL_CMS)
    np.testing.assert_allclose(ours[rows, 2], ref["abias_cms2"], rtol=0, atol=BIAS_TOL_CMS2)


@pytest.mark.parametrize("mode", list(REFERENCE_RUNS))
def test_mode_defaults_are_the_reference_parameters(mode: Kf3Mode) -> None:
    tag, _ = REFERENCE_RUNS[mode]
    ref = _reference(tag)
    d = _inputs()
    # The project-unit batch with `mode` and the reference preset: the mode's variances, P0
    # and m <-> cm conversion.
    r = run_batch(d["z_baro_cm"] / 100.0, d["a_meas_cms2"] / 100.0, DT_S,
                  {"mode": mode.value, "preset": "reference"})
    rows = ref["idx"].astype(int)
    np.testing.assert_allclose(r.altitude_m[rows] * 100.0, ref["z_cm"], rtol=0, atol=ALT_TOL_CM)
    np.testing.assert_allclose(r.climb_m_s[rows] * 100.0, ref["v_cms"], rtol=0, atol=CLIMB_TOL_CMS)
    assert r.accel_bias_m_s2 is not None
    np.testing.assert_allclose(r.accel_bias_m_s2[rows] * 100.0, ref["abias_cms2"], rtol=0,
                               atol=BIAS_TOL_CMS2)


def test_avario_ignores_the_configured_accel_variance() -> None:
    d = _inputs()
    runs = []
    for accel_variance in (100.0, 123_456.0):
        kf = Kalman3(Kf3Mode.AVARIO)
        kf.configure(200.0, accel_variance, 1.0, z0=float(d["z_baro_cm"][0]))
        kf.step(float(d["z_baro_cm"][1]), float(d["a_meas_cms2"][1]), DT_S)
        runs.append((kf.x.copy(), kf.accel_variance))
    np.testing.assert_array_equal(runs[0][0], runs[1][0])
    assert 1.0 <= runs[0][1] <= 50.0


def test_esp32_and_y2021_predictions_differ_only_in_the_order_of_z_and_v() -> None:
    semi, explicit = Kalman3(Kf3Mode.ESP32), Kalman3(Kf3Mode.Y2021)
    for kf in (semi, explicit):
        kf.configure(1.0, 1.0, 0.0, z0=0.0, v0=10.0, bias0=2.0)
        kf.predict(a_meas=12.0, dt=0.5)  # true accel 10 cm/s^2
    assert semi.v == explicit.v == pytest.approx(15.0)
    assert semi.z == pytest.approx(0.5 * 15.0)  # z moved with the new v
    assert explicit.z == pytest.approx(0.5 * 10.0)  # z moved with the old v
