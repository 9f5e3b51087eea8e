"""Magnetometer calibration on the simulated figure of 8: the ellipsoid fit recovers hard iron
within 1 uT and the soft-iron matrix within 2 % per element; min/max recovers hard iron and
per-axis scale; too little coverage and a disturbed field are refused with what to do."""

from __future__ import annotations

import re

import numpy as np
import pytest
from tests.calibration.conftest import HARD_IRON_UT, SOFT_IRON, make_stream

from imuhal.calibration.errors import CalibrationError
from imuhal.calibration.mag import (
    MagCalibrationProcedure,
    MagSettings,
    ellipsoid_fit,
    evaluate,
    minmax_fit,
)
from imuhal.calibration.sphere import coverage
from imuhal.core.samples import MagSample, Sample
from imuhal.emulation import PhysicalInputs
from imuhal.sim.calibration import CalibrationScenario
from imuhal.sim.errors import SensorErrorSpec

FIELD_UT = 41.0  # the simulator's default environment
TRUE_S = np.linalg.inv(np.asarray(SOFT_IRON))


def _mag(samples: list[Sample]) -> np.ndarray:
    return np.array([s.mag_ut for s in samples if isinstance(s, MagSample)])


@pytest.fixture(scope="module")
def figure8(calibration_run: list[Sample]) -> np.ndarray:
    return _mag([s for s in calibration_run if s.t_ns >= 42e9])


def test_ellipsoid_fit_recovers_hard_iron_within_1_ut_and_soft_iron_within_2_percent(
        figure8: np.ndarray) -> None:
    result = evaluate(figure8, MagSettings(field_ut=FIELD_UT))
    assert np.abs(result.fit.hard_iron_ut - HARD_IRON_UT).max() < 1.0
    assert np.abs(result.fit.soft_iron - TRUE_S).max() < 0.02
    assert np.allclose(result.fit.soft_iron, result.fit.soft_iron.T)  # symmetric
    assert np.all(np.linalg.eigvalsh(result.fit.soft_iron) > 0)      # positive definite
    assert result.quality["residual_rms_ut"] < 0.5                    # 0.2 uT noise


def test_without_a_field_strength_the_fit_keeps_volume_and_reports_the_strength(
        figure8: np.ndarray) -> None:
    fit = ellipsoid_fit(figure8)
    assert np.linalg.det(fit.soft_iron) == pytest.approx(1.0, abs=1e-9)
    expected = TRUE_S / np.cbrt(np.linalg.det(TRUE_S))  # the shape, at unit volume
    assert np.abs(fit.soft_iron - expected).max() < 0.02
    # B = the true 41 uT stretched by the soft iron's volume change
    assert fit.field_ut == pytest.approx(FIELD_UT * np.cbrt(np.linalg.det(SOFT_IRON)), rel=0.01)


def test_minmax_recovers_hard_iron_and_per_axis_scale_without_cross_coupling() -> None:
    # min/max needs every axis's extremes: a wide figure of 8 (roll +-120, pitch +-80 deg)
    spec = SensorErrorSpec.model_validate({"mag": {
        "noise_std": 0.2, "hard_iron_ut": HARD_IRON_UT,
        "soft_iron": ((1.06, 0, 0), (0, 0.95, 0), (0, 0, 1.02))}})
    wide = CalibrationScenario({"positions": (("+z down", 0.0, 0.0),), "figure8_cycles": 5,
                                "figure8_roll_deg": 120.0, "figure8_pitch_deg": 80.0}, seed=3)
    raw = _mag(make_stream(wide, spec, mag_every=1, t1=wide.phases()[-1].end_s))
    fit = minmax_fit(raw, FIELD_UT)
    assert np.abs(fit.hard_iron_ut - HARD_IRON_UT).max() < 1.0
    assert np.diag(fit.soft_iron) == pytest.approx([1 / 1.06, 1 / 0.95, 1 / 1.02], rel=0.02)


def test_minmax_on_cross_coupled_soft_iron_is_refused_pointing_to_the_ellipsoid(
        figure8: np.ndarray) -> None:
    with pytest.raises(CalibrationError, match="--method ellipsoid"):
        evaluate(figure8, MagSettings(method="minmax"))


def test_level_turns_alone_are_refused_for_coverage_with_what_to_do(
        calibration_run: list[Sample]) -> None:
    # the first two holds and the turn between them: not a figure of 8
    raw = _mag([s for s in calibration_run if s.t_ns < 11e9])
    with pytest.raises(CalibrationError, match=r"covered \d+ % of field directions") as exc:
        evaluate(raw)
    assert "figure of 8" in str(exc.value)
    assert exc.value.figures["coverage_pct"] < 50


def test_a_still_board_does_not_count_as_coverage(calibration_run: list[Sample]) -> None:
    raw = _mag([s for s in calibration_run if s.t_ns < 4e9])  # noise around one point
    with pytest.raises(CalibrationError, match="covered 0 %"):
        evaluate(raw, MagSettings(min_samples=100))


def test_a_disturbed_field_is_refused(calibration_scenario: CalibrationScenario) -> None:
    def steel_nearby(t: float, m: PhysicalInputs) -> PhysicalInputs:
        # a 12 uT offset switching on and off every 3 s (a passing steel object)
        if int(t / 3.0) % 2:
            x, y, z = m.magnetic_field_ut
            return PhysicalInputs(magnetic_field_ut=(x + 12.0, y - 6.0, z))
        return m

    raw = _mag(make_stream(calibration_scenario, t0=42.0, t1=76.0, transform=steel_nearby))
    with pytest.raises(CalibrationError, match="disturbed") as exc:
        evaluate(raw)
    assert "move away" in str(exc.value).lower()


def test_the_procedure_stops_once_directions_are_covered(calibration_run: list[Sample]) -> None:
    proc = MagCalibrationProcedure(MagSettings(target_coverage=0.7, field_ut=FIELD_UT))
    result = proc.run(calibration_run)
    assert proc.done and result.samples < len(_mag(calibration_run))
    assert result.coverage.fraction >= 0.5
    assert np.abs(result.fit.hard_iron_ut - HARD_IRON_UT).max() < 1.0
    assert result.record().procedure == "mag-ellipsoid"


def test_coverage_counts_equal_area_cells_and_names_missing_axes() -> None:
    rng = np.random.default_rng(1)
    sphere = rng.normal(size=(5000, 3))
    upper = sphere[sphere[:, 2] > 0]
    assert coverage(sphere).fraction == 1.0
    half = coverage(upper)
    assert half.fraction == pytest.approx(0.5)
    assert half.missing_axes == ("-z",)


def test_minmax_on_the_calibration_scenario_names_the_axes_never_turned_onto_the_field(
        calibration_run: list[Sample]) -> None:
    # The scenario's figure of 8 covers directions well enough for the ellipsoid but never
    # points every axis along the field: min/max cannot work, and says which axes and by how
    # much (issue 12 item 5).
    with pytest.raises(CalibrationError) as exc:
        evaluate(_mag(calibration_run), MagSettings(method="minmax"))
    message = str(exc.value)
    assert re.search(r"never turned these sensor axes onto the field direction: [+-][xyz] by "
                     r"\d+ deg", message), message
    assert "--method ellipsoid" in message


def test_the_final_coverage_is_the_last_coverage_shown_live(
        calibration_run: list[Sample]) -> None:
    shown: list[str] = []
    proc = MagCalibrationProcedure(MagSettings(target_coverage=0.7, field_ut=FIELD_UT),
                                   progress=lambda p: shown.append(p.message))
    result = proc.run(calibration_run)
    live = [float(m) for m in re.findall(r"^coverage (\d+) %", "\n".join(shown), re.M)]
    assert proc.done and live
    assert f"{result.quality['coverage_pct']:.0f}" == f"{live[-1]:.0f}"
    assert result.coverage.fraction == proc.coverage
