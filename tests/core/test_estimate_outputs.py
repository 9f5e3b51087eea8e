"""Estimates are frozen records; the fast ``build`` makes exactly what the constructor does."""

from __future__ import annotations

import pytest

from imuhal.estimation.outputs import AttitudeEstimate


@pytest.mark.parametrize("linear_accel", [None, (0.25, -0.0, 9.5)])
def test_attitude_build_makes_the_same_estimate_as_the_keyword_constructor(
        linear_accel: tuple[float, float, float] | None) -> None:
    q = (0.5, 0.5, -0.5, 0.5)
    built = AttitudeEstimate.build(11, "ahrs", q, linear_accel, {"dt_s": 0.004})
    kw = AttitudeEstimate(t_ns=11, source="ahrs", q_body_to_ned=q,
                          linear_accel_ned_m_s2=linear_accel, diagnostics={"dt_s": 0.004})
    assert type(built) is AttitudeEstimate and built == kw and repr(built) == repr(kw)
    with pytest.raises(AttributeError):
        built.t_ns = 12  # still frozen
