"""The calibration records' arithmetic, written out by hand: what ``apply`` does to one raw
sensor-frame reading (docs/calibration.md: corrected = M (diag(scale) (raw - offset)) for the
inertial sensors, S (raw - h) for the magnetometer)."""

from __future__ import annotations

import pytest

from imuhal.calibration.model import AccelCalibration, GyroCalibration, MagCalibration

RAW = (1.0, -2.0, 3.0)
# Not symmetric, so a row read as a column shows.
SKEWED = ((1.0, 0.02, -0.01), (0.0, 1.0, 0.03), (0.015, 0.0, 1.0))


def _by_hand(m: tuple[tuple[float, ...], ...], v: tuple[float, ...]) -> tuple[float, ...]:
    return tuple(sum(m[i][k] * v[k] for k in range(3)) for i in range(3))


@pytest.mark.parametrize("record", [AccelCalibration, GyroCalibration])
def test_inertial_record_subtracts_offset_scales_then_applies_misalignment_rows(
        record: type) -> None:
    offset_field = "offset_m_s2" if record is AccelCalibration else "offset_rad_s"
    cal = record(**{offset_field: (0.1, 0.2, -0.3)}, scale=(1.01, 0.99, 1.02),
                 misalignment=SKEWED)
    scaled = ((1.0 - 0.1) * 1.01, (-2.0 - 0.2) * 0.99, (3.0 + 0.3) * 1.02)
    assert cal.apply(RAW) == pytest.approx(_by_hand(SKEWED, scaled), abs=1e-12)


def test_mag_record_subtracts_hard_iron_then_applies_soft_iron_rows() -> None:
    cal = MagCalibration(hard_iron_ut=(5.0, -6.0, 7.0), soft_iron=SKEWED)
    assert cal.apply(RAW) == pytest.approx(_by_hand(SKEWED, (-4.0, 4.0, -4.0)), abs=1e-12)
