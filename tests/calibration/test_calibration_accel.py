"""Accelerometer six-position calibration: the seed's formulas, the procedure on the simulated
six positions (offsets within 5 mg, scale within 0.2 %), the optional 3x3 misalignment fit,
the residual gravity error, and refusal when the board never holds the positions."""

from __future__ import annotations

import numpy as np
import pytest
from tests.calibration.conftest import (
    ACCEL_BIAS_MG,
    ACCEL_CROSS,
    ACCEL_SCALE,
    MG,
    make_stream,
)

from imuhal.calibration.accel import (
    SIX_POSITIONS,
    AccelSixPosition,
    AccelSixSettings,
    expected_specific_force,
    six_position_fit,
)
from imuhal.calibration.errors import CalibrationError
from imuhal.calibration.progress import Progress, ProgressKind
from imuhal.core.samples import Sample
from imuhal.sim.tumble import TumbleScenario

G = 9.80665
TRUE_GAIN = (np.eye(3) + np.asarray(ACCEL_CROSS)) @ np.diag(1 + np.asarray(ACCEL_SCALE))


def test_seed_formulas_give_offset_and_sensitivity_per_axis() -> None:
    # axis reads gain * true + offset; up = +g, down = -g
    gain, offset = np.array([1.02, 0.97, 1.005]), np.array([0.3, -0.2, 0.5])
    means = {p: gain * expected_specific_force(p) + offset for p in SIX_POSITIONS}
    b, s = six_position_fit(means)
    assert b == pytest.approx(offset, abs=1e-12)
    assert s == pytest.approx(1 / gain, rel=1e-12)


def test_six_positions_recover_offsets_within_5_mg_and_scale_within_0_2_percent(
        calibration_run: list[Sample]) -> None:
    result = AccelSixPosition().run(calibration_run)
    assert np.abs(result.offset_m_s2 / MG - np.array(ACCEL_BIAS_MG)).max() < 5.0
    assert result.scale == pytest.approx(1 / (1 + np.asarray(ACCEL_SCALE)), rel=2e-3)
    assert set(result.means) == set(SIX_POSITIONS)


def test_least_squares_recovers_the_full_misalignment_within_0_1_percent(
        calibration_run: list[Sample]) -> None:
    result = AccelSixPosition(AccelSixSettings(misalignment=True)).run(calibration_run)
    a = result.misalignment @ np.diag(result.scale)
    assert np.abs(a - np.linalg.inv(TRUE_GAIN)).max() < 1e-3
    assert np.diag(result.misalignment) == pytest.approx(1.0)
    assert np.abs(result.offset_m_s2 / MG - np.array(ACCEL_BIAS_MG)).max() < 5.0
    assert result.procedure == "accel-six-position-lsq"


def test_residual_gravity_error_is_reported_and_shrinks(calibration_run: list[Sample]) -> None:
    plain = AccelSixPosition().run(calibration_run).quality
    full = AccelSixPosition(AccelSixSettings(misalignment=True)).run(calibration_run).quality
    assert plain["uncalibrated_gravity_error_rms_mg"] > 20  # ~40-60 mg offsets, 1-2 % scale
    assert plain["gravity_error_rms_mg"] < 2.0              # cross-axis left: second order
    assert full["gravity_error_max_mg"] < 0.5


def test_the_user_is_guided_position_by_position(calibration_run: list[Sample]) -> None:
    events: list[Progress] = []
    AccelSixPosition(progress=events.append).run(calibration_run)
    asked = [e for e in events if e.kind is ProgressKind.INSTRUCTION]
    recorded = [e.step for e in events if e.kind is ProgressKind.STEP_DONE]
    assert len(asked) == 6 and asked[0].message.startswith("position 1/6")
    assert sorted(recorded) == sorted({"+x down", "-x down", "+y down", "-y down", "+z down",
                                       "-z down"})


def test_a_tumbling_board_records_no_position_and_is_refused() -> None:
    stream = make_stream(TumbleScenario(seed=2), t0=33.0, t1=44.0)  # the free tumble
    with pytest.raises(CalibrationError, match="only 0 of 6") as exc:
        AccelSixPosition().run(stream)
    assert "hold it still" in str(exc.value)


def test_a_position_held_while_creeping_is_not_recorded(calibration_run: list[Sample]) -> None:
    # the first hold only, with a slow 30 mg/s creep on x: still enough for the window,
    # but the two halves of the average disagree, so nothing is recorded
    creeping = []
    for s in calibration_run:
        if s.t_ns > 4e9:
            break
        if s.channel.value == "accel":
            a = s.vector
            s = s.with_vector((a[0] + 0.03 * G * s.t_ns / 1e9, a[1], a[2]), s.frame)
        creeping.append(s)
    proc = AccelSixPosition()
    with pytest.raises(CalibrationError):
        proc.run(creeping)
    assert proc.means == {}
