"""The ISA troposphere both ways, against published standard-atmosphere values."""

from __future__ import annotations

import pytest

from imuhal.core.atmosphere import altitude_m_from_pressure, pressure_pa_at_altitude


@pytest.mark.parametrize(
    ("altitude_m", "pressure_pa"),
    [(0, 101325.0), (1000, 89874.6), (2000, 79495.2), (5000, 54019.9)],
)
def test_pressure_matches_published_isa_table(altitude_m: float, pressure_pa: float) -> None:
    assert pressure_pa_at_altitude(altitude_m) == pytest.approx(pressure_pa, abs=1.0)


def test_altitude_inverts_pressure() -> None:
    for h in (-300.0, 0.0, 920.0, 4321.0):
        assert altitude_m_from_pressure(pressure_pa_at_altitude(h)) == pytest.approx(h, abs=1e-6)


def test_sea_level_reference_shifts_the_altitude() -> None:
    qnh = 102000.0
    assert altitude_m_from_pressure(qnh, sea_level_pa=qnh) == pytest.approx(0.0, abs=1e-9)


def test_non_positive_pressure_is_refused() -> None:
    with pytest.raises(ValueError, match="positive"):
        altitude_m_from_pressure(0.0)
